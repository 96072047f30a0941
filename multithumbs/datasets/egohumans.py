"""EgoHumans (ICCV 2023) and Harmony4D (NeurIPS 2024): one loader, two world alignments.

Both datasets come from the same capture pipeline (DATASETS.md §1-2). A sequence folder holds::

    colmap/workplace/{cameras,images,points3D}.txt    COLMAP text model (exo GoPros: OPENCV_FISHEYE)
    colmap/workplace/scale.npy                        Harmony4D "exo" mode: 4x4 COLMAP -> metric
    colmap/workplace/colmap_from_aria_transforms.pkl  otherwise: {'aria01': 4x4 aria world -> COLMAP, ...}
    exo/camXX/images/00001.jpg                        raw fisheye frames (undistorted_images/ if made)
    processed_data/smpl/00001.npy                     {'aria01': {global_orient, body_pose, betas,
                                                       transl, vertices, joints (45, 3)}, ...}

World alignment: ``T_align = inv(scale.npy)`` when ``scale.npy`` exists (the world is metric COLMAP),
else ``T_align = colmap_from_aria['aria01']`` for EVERY camera (the world is aria01's metric SLAM
world; a per-person transform misplaces the other subjects). The world-to-camera matrix
``E = [R|t]_colmap @ T_align`` may carry a scale, removed by
:func:`multithumbs.datasets.cameras.metric_extrinsics`.

Decisions where the datasets are silent (documented here, flagged [verify] in DATASETS.md):

- COLMAP's camera parameters are used as OpenCV parameters unchanged, as the datasets' own code does
  (no half-pixel shift).
- An exo camera's pose is that of its registered image with the smallest name (they are static).
  Cameras with no registered image (the configs' ``MANUAL_EXO_CAMERAS``) are left out, with a note.
  COLMAP cameras of 1408x1408 are Aria cameras and are left out.
- Frame ids are the stems of ``processed_data/smpl/*.npy`` (1-based, five digits).
- The frame rate is not recorded in the data: :data:`DEFAULT_FPS` (a spec can override it).
"""

from __future__ import annotations

import pickle
from pathlib import Path
from typing import Sequence

import numpy as np

from multithumbs.conventions import NUM_BETAS, NUM_BODY_JOINTS, NUM_JOINTS
from multithumbs.datasets.cameras import Camera, metric_extrinsics
from multithumbs.datasets.sequence import MultiViewSequence, PeopleSeries, read_betas, require_files, smpl_array
from multithumbs.errors import InputError

WORKPLACE = Path("colmap/workplace")
COLMAP_FILES = ("cameras.txt", "images.txt", "points3D.txt")
ARIA_TRANSFORMS = "colmap_from_aria_transforms.pkl"
SCALE_FILE = "scale.npy"
SMPL_DIR = Path("processed_data/smpl")
ANCHOR_PERSON = "aria01"
"""The person whose Aria world is the world frame of every camera (DATASETS.md §1)."""

ARIA_IMAGE_SIZE = (1408, 1408)
"""COLMAP cameras of this size are the Aria glasses' (not static exo cameras)."""

DEFAULT_FPS = {"egohumans": 20.0, "harmony4d": 20.0}
"""Frames per second assumed when a spec gives none. Neither dataset records its processed frame rate
[verify on real data]; set ``fps`` in the spec when you know it."""

HARMONY4D_SPLITS = ("train", "test")


def find_sequences(root: str | Path, dataset: str) -> list[str]:
    """Sequence names under a data root: ``<activity>/<sequence>`` (EgoHumans) or
    ``<split>/<activity>/<sequence>`` (Harmony4D), every folder that holds ``colmap/`` or ``processed_data/``."""
    root = Path(root)
    levels = 3 if dataset == "harmony4d" else 2
    found = []
    for path in sorted(root.glob("/".join(["*"] * levels))):
        if path.is_dir() and ((path / "colmap").is_dir() or (path / "processed_data").is_dir()):
            found.append(path.relative_to(root).as_posix())
    return found


def check_layout(seq_dir: Path) -> None:
    """Raise InputError naming the first file a sequence folder lacks."""
    what = "EgoHumans/Harmony4D sequence layout"
    if not seq_dir.is_dir():
        raise InputError(f"{seq_dir}: no such sequence folder")
    require_files(seq_dir, [str(WORKPLACE / name) for name in COLMAP_FILES], what)
    if not (seq_dir / WORKPLACE / SCALE_FILE).is_file() and not (seq_dir / WORKPLACE / ARIA_TRANSFORMS).is_file():
        raise InputError(f"{seq_dir / WORKPLACE / ARIA_TRANSFORMS}: missing (needed to align the world; "
                         f"Harmony4D exo-only sequences have {SCALE_FILE} instead)")
    require_files(seq_dir, ["exo", str(SMPL_DIR)], what)
    if not any((seq_dir / SMPL_DIR).glob("*.npy")):
        raise InputError(f"{seq_dir / SMPL_DIR / '00001.npy'}: missing (no SMPL ground-truth frames)")


def alignment_transform(workplace: Path) -> tuple[np.ndarray, str]:
    """``T_align`` (4x4, dataset world -> COLMAP world) and the alignment's label."""
    scale_path = workplace / SCALE_FILE
    if scale_path.is_file():
        try:
            scale = np.load(scale_path, allow_pickle=False)
        except (OSError, ValueError) as error:
            raise InputError(f"{scale_path}: not a readable .npy ({error})") from None
        if scale.shape != (4, 4) or not np.all(np.isfinite(scale)) or abs(np.linalg.det(scale)) < 1e-12:
            raise InputError(f"{scale_path}: expected an invertible 4x4 COLMAP-to-metric transform, got shape {scale.shape}")
        return np.linalg.inv(scale), SCALE_FILE
    path = workplace / ARIA_TRANSFORMS
    transforms = _load_pickle(path)
    if not isinstance(transforms, dict) or ANCHOR_PERSON not in transforms:
        raise InputError(f"{path}: expected a dict with an {ANCHOR_PERSON!r} 4x4 transform")
    anchor = np.asarray(transforms[ANCHOR_PERSON], dtype=np.float64)
    if anchor.shape != (4, 4) or not np.all(np.isfinite(anchor)):
        raise InputError(f"{path}: {ANCHOR_PERSON!r} is not a finite 4x4 matrix (shape {anchor.shape})")
    return anchor, f"colmap+aria:{ANCHOR_PERSON}"


def read_exo_cameras(seq_dir: Path, align: np.ndarray, exclude: Sequence[str] = ()) -> tuple[list[Camera], list[str]]:
    """The static exo cameras (metric, world frame of ``align``) and notes on cameras left out."""
    import pycolmap

    workplace = seq_dir / WORKPLACE
    try:
        model = pycolmap.Reconstruction(str(workplace))
    except Exception as error:  # pycolmap raises RuntimeError/ValueError with its own text
        reason = str(error).splitlines()[0] if str(error) else type(error).__name__
        raise InputError(f"{workplace}: COLMAP text model cannot be read ({reason})") from None
    by_camera: dict[str, list] = {}
    for image in model.images.values():
        name = Path(image.name).parts[0] if len(Path(image.name).parts) > 1 else Path(image.name).stem
        by_camera.setdefault(name, []).append(image)
    exo_dirs = sorted(p.name for p in (seq_dir / "exo").iterdir() if p.is_dir()) if (seq_dir / "exo").is_dir() else []
    cameras, notes = [], []
    for name in sorted(set(by_camera) | set(exo_dirs)):
        if name in exclude:
            notes.append(f"{name}: excluded")
            continue
        images = sorted(by_camera.get(name, []), key=lambda im: im.name)
        if not images:
            notes.append(f"{name}: no registered image in images.txt (a manual camera), left out")
            continue
        colmap_cam = model.cameras[images[0].camera_id]
        size = (int(colmap_cam.height), int(colmap_cam.width))
        if size == ARIA_IMAGE_SIZE:
            continue  # an Aria camera
        if name not in exo_dirs:
            notes.append(f"{name}: registered but has no exo/{name} folder, left out")
            continue
        pose = images[0].cam_from_world() if callable(images[0].cam_from_world) else images[0].cam_from_world
        world_to_colmap_cam = np.eye(4)
        world_to_colmap_cam[:3, :3] = pose.rotation.matrix()
        world_to_colmap_cam[:3, 3] = pose.translation
        R, t, _ = metric_extrinsics(world_to_colmap_cam @ align, f"{workplace / 'images.txt'} camera {name}")
        K, dist, lens = _intrinsics(colmap_cam, f"{workplace / 'cameras.txt'} camera {name}")
        cameras.append(Camera(name, K, dist, lens, R, t, size))
    return cameras, notes


def _intrinsics(camera, where: str) -> tuple[np.ndarray, np.ndarray, str]:
    model = camera.model.name if hasattr(camera.model, "name") else str(camera.model)
    p = np.asarray(camera.params, dtype=np.float64)
    if model == "OPENCV_FISHEYE":
        fx, fy, cx, cy, *dist = p
        lens = "fisheye"
    elif model == "OPENCV":
        fx, fy, cx, cy, *dist = p
        lens = "radial"
    elif model == "PINHOLE":
        (fx, fy, cx, cy), dist, lens = p, [], "pinhole"
    elif model == "SIMPLE_PINHOLE":
        (fx, cx, cy), dist, lens = p, [], "pinhole"
        fy = fx
    else:
        raise InputError(f"{where}: camera model {model} is not supported (OPENCV_FISHEYE, OPENCV, PINHOLE)")
    return np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]]), np.asarray(dist), lens


def smpl_frame_ids(smpl_dir: Path) -> np.ndarray:
    """Frame ids of the ground-truth files ``{t:05d}.npy`` (increasing)."""
    ids = []
    for path in smpl_dir.glob("*.npy"):
        if not path.stem.isdigit():
            raise InputError(f"{path}: ground-truth files are named by frame id ({{t:05d}}.npy)")
        ids.append(int(path.stem))
    ids.sort()
    if ids and ids[0] < 1:
        raise InputError(f"{smpl_dir / f'{ids[0]:05d}.npy'}: frame ids start at 1 (0 is an invalid time stamp)")
    return np.asarray(ids, dtype=np.int64)


def load_frame_dict(path: Path) -> dict:
    """One ground-truth frame: ``{person: {field: array}}``."""
    if not path.is_file():
        raise InputError(f"{path}: missing ground-truth frame")
    try:
        data = np.load(path, allow_pickle=True)
        data = data.item() if data.dtype == object and data.shape == () else data
    except (OSError, ValueError, pickle.UnpicklingError, EOFError) as error:
        raise InputError(f"{path}: not a readable ground-truth .npy ({type(error).__name__})") from None
    if not isinstance(data, dict):
        raise InputError(f"{path}: expected a pickled dict keyed by person, got {type(data).__name__}")
    return data


def read_people(smpl_dir: Path, frame_ids: np.ndarray, names: Sequence[str], with_vertices: bool) -> PeopleSeries:
    """Stored SMPL parameters, joints (first 24 of ``smpl_45``) and optionally vertices; absent people are gaps."""
    p, t = len(names), len(frame_ids)
    orient, pose = np.zeros((p, t, 3)), np.zeros((p, t, NUM_BODY_JOINTS, 3))
    betas, transl = np.zeros((p, t, NUM_BETAS)), np.zeros((p, t, 3))
    joints, valid = np.zeros((p, t, NUM_JOINTS, 3)), np.zeros((p, t), bool)
    vertices: np.ndarray | None = None
    for j, frame_id in enumerate(frame_ids):
        path = smpl_dir / f"{int(frame_id):05d}.npy"
        frame = load_frame_dict(path)
        for i, name in enumerate(names):
            person = frame.get(name)
            if person is None:
                continue  # absent at this frame: a gap
            where = f"{path} person {name}"
            for key in ("global_orient", "body_pose", "betas", "transl", "joints"):
                if key not in person:
                    raise InputError(f"{where}: missing field {key!r}")
            orient[i, j] = smpl_array(person["global_orient"], (3,), f"{where} global_orient")
            pose[i, j] = smpl_array(person["body_pose"], (NUM_BODY_JOINTS * 3,), f"{where} body_pose").reshape(-1, 3)
            betas[i, j] = read_betas(person["betas"], f"{where} betas")
            transl[i, j] = smpl_array(person["transl"], (3,), f"{where} transl")
            stored = np.asarray(person["joints"], dtype=np.float64)
            if stored.ndim != 2 or stored.shape[1] != 3 or stored.shape[0] < NUM_JOINTS or not np.all(np.isfinite(stored)):
                raise InputError(f"{where} joints: expected (45, 3) smpl_45 joints, got shape {stored.shape}")
            joints[i, j] = stored[:NUM_JOINTS]
            if with_vertices:
                if "vertices" not in person:
                    raise InputError(f"{where}: missing field 'vertices'")
                verts = np.asarray(person["vertices"], dtype=np.float32)
                if verts.ndim != 2 or verts.shape[1] != 3:
                    raise InputError(f"{where} vertices: expected (V, 3), got shape {verts.shape}")
                if vertices is None:
                    vertices = np.zeros((p, t, verts.shape[0], 3), np.float32)
                elif verts.shape[0] != vertices.shape[2]:
                    raise InputError(f"{where} vertices: {verts.shape[0]} vertices, earlier frames have {vertices.shape[2]}")
                vertices[i, j] = verts
            valid[i, j] = True
    if with_vertices and vertices is None:
        vertices = np.zeros((p, t, 0, 3), np.float32)
    return PeopleSeries(tuple(names), np.asarray(frame_ids, np.int64), orient, pose, betas, transl, joints, valid,
                        ("neutral",) * p, vertices)


def sample_people(smpl_dir: Path, frame_ids: np.ndarray, samples: int = 8) -> tuple[str, ...]:
    """People present in up to ``samples`` evenly spaced ground-truth frames (reading every frame of a long
    sequence just to list it would take minutes)."""
    if not len(frame_ids):
        return ()
    picks = np.unique(np.linspace(0, len(frame_ids) - 1, min(samples, len(frame_ids))).round().astype(int))
    names: set[str] = set()
    for k in picks:
        names.update(str(n) for n in load_frame_dict(smpl_dir / f"{int(frame_ids[k]):05d}.npy"))
    return tuple(sorted(names))


def load_egohumans(root: str | Path, sequence: str, dataset: str = "egohumans", fps: float | None = None,
                   exclude_cameras: Sequence[str] = (), exclude_people: Sequence[str] = ()) -> MultiViewSequence:
    """Load one EgoHumans or Harmony4D sequence.

    Args:
        root: the data root (``<root>/<activity>/<sequence>`` for EgoHumans,
            ``<root>/<split>/<activity>/<sequence>`` for Harmony4D).
        sequence: the sequence's path under ``root``.
        dataset: ``"egohumans"`` or ``"harmony4d"`` (labels and the default frame rate; the alignment
            mode follows the files present).
        fps: frames per second, default :data:`DEFAULT_FPS`.
        exclude_cameras: camera names to leave out (the configs' ``INVALID_EXOS``).
        exclude_people: person names to leave out (the configs' ``INVALID_ARIAS``).
    """
    if dataset not in DEFAULT_FPS:
        raise InputError(f"dataset: expected 'egohumans' or 'harmony4d', got {dataset!r}")
    root = Path(root)
    seq_dir = root / sequence
    check_layout(seq_dir)
    align, label = alignment_transform(seq_dir / WORKPLACE)
    cameras, notes = read_exo_cameras(seq_dir, align, exclude_cameras)
    if not cameras:
        raise InputError(f"{seq_dir / WORKPLACE / 'images.txt'}: no usable exo camera registered")
    smpl_dir = seq_dir / SMPL_DIR
    frame_ids = smpl_frame_ids(smpl_dir)
    people = tuple(n for n in sample_people(smpl_dir, frame_ids) if n not in exclude_people)
    if exclude_people:
        notes.append("excluded people: " + ", ".join(exclude_people))

    def image_path(camera: str, frame_id: int, undistorted: bool) -> tuple[Path, bool]:
        ready = seq_dir / "exo" / camera / "undistorted_images" / f"{frame_id:05d}.jpg"
        if undistorted and ready.is_file():
            return ready, True
        return seq_dir / "exo" / camera / "images" / f"{frame_id:05d}.jpg", False

    def people_reader(ids: np.ndarray, names: Sequence[str], with_vertices: bool) -> PeopleSeries:
        return read_people(smpl_dir, ids, names, with_vertices)

    return MultiViewSequence(dataset, sequence, seq_dir, tuple(cameras), frame_ids,
                             float(fps or DEFAULT_FPS[dataset]), people, label, tuple(notes), image_path, people_reader)


def _load_pickle(path: Path):
    if not path.is_file():
        raise InputError(f"{path}: missing")
    try:
        with open(path, "rb") as file:
            return pickle.load(file, encoding="latin1")
    except Exception as error:  # pickle raises many types for a broken file
        raise InputError(f"{path}: not a readable pickle ({type(error).__name__})") from None


__all__ = ["ANCHOR_PERSON", "DEFAULT_FPS", "alignment_transform", "check_layout", "find_sequences",
           "load_egohumans", "read_exo_cameras", "read_people", "smpl_frame_ids"]
