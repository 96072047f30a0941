"""Edited real videos for the GT-free metrics: AVA clips (as the Multishot repository prepares them) and
the sitcom annotations (cross-shot human pairs).

Both give an :class:`EditedClip`: frames (image files, read on demand), the cuts, the people under one
identity each across the cuts where the data links them, and their OpenPose BODY_25 keypoints, also
mapped to SMPL's joint order for :func:`multithumbs.metrics.gt_free.cross_shot_pck` (only joints with the
same meaning are mapped, :data:`BODY25_TO_SMPL`; the rest get confidence 0).

AVA (DATASETS.md §4): ``{root}/{train,val}/midframes/<video>/{sec:04d}.jpg`` (1 fps) or
``allframes/<video>/{sec:04d}_{k:02d}.jpg`` (25 fps); ``ava_{train,val}_v2.2.csv`` rows
``video_id, sec, x1, y1, x2, y2 (normalised), action_id, person_id``; a clip is one npz written by the
Multishot ``process_phalp.py`` (``imgname``, ``shot``, ``body_keypoints (T, 25, 3)``, ``valid``...):
one person followed across a shot change. AVA's ``person_id`` links boxes within a few seconds, not
across shots, so it is not used as a cross-shot identity.

Sitcoms (``ethanweber/sitcoms3D``): ``human_data/<loc>.json`` ``{image: [{openpose_keypoints, smpl?}]}``
and ``human_pairs/<loc>.json`` ``[[img_a, idx_a, img_b, idx_b], ...]``, the only cross-shot identity
labels. Each pair of images becomes a two-frame clip with a cut at frame 1; every human of both images
is a person, the linked ones sharing one id. The episode frames are not distributed: users dump them
(``<Show>_S08E07_%08d.jpg``) into ``images/<loc>/`` or ``sparse_reconstruction_and_nerf_data/<loc>/images/``.
``cameras.json``, when present, gives each image's intrinsics and pose (the reconstruction's scale).
"""

from __future__ import annotations

import csv
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterator

import numpy as np

from multithumbs.conventions import NUM_JOINTS
from multithumbs.datasets.sequence import read_rgb
from multithumbs.errors import InputError
from multithumbs.io import read_json
from multithumbs.types import Shots

BODY25_TO_SMPL = {
    0: 8,    # pelvis <- MidHip
    1: 12,   # left hip <- LHip
    2: 9,    # right hip <- RHip
    4: 13,   # left knee <- LKnee
    5: 10,   # right knee <- RKnee
    7: 14,   # left ankle <- LAnkle
    8: 11,   # right ankle <- RAnkle
    12: 1,   # neck <- Neck
    16: 5,   # left shoulder <- LShoulder
    17: 2,   # right shoulder <- RShoulder
    18: 6,   # left elbow <- LElbow
    19: 3,   # right elbow <- RElbow
    20: 7,   # left wrist <- LWrist
    21: 4,   # right wrist <- RWrist
}
"""SMPL joint <- OpenPose BODY_25 keypoint, for the joints that mean the same point (SMPLify's pairing).
Spine, collars, head, feet and hands have no BODY_25 counterpart and are left unobserved."""

BODY25 = 25
AVA_MIDFRAMES_FPS = 1.0
AVA_ALLFRAMES_FPS = 25.0
SITCOM_FPS = 24.0
"""Nominal rate for sitcom pairs (two frames across a cut: the rate only scales time, nothing measures it)."""


def body25_to_smpl(keypoints: np.ndarray) -> np.ndarray:
    """``(..., 25, 3)`` OpenPose BODY_25 ``u, v, confidence`` to ``(..., 24, 3)`` in SMPL order (unmapped: 0)."""
    keypoints = np.asarray(keypoints, dtype=np.float64)
    if keypoints.shape[-2:] != (BODY25, 3):
        raise InputError(f"keypoints: expected OpenPose BODY_25 (..., 25, 3), got {keypoints.shape}")
    out = np.zeros((*keypoints.shape[:-2], NUM_JOINTS, 3))
    for smpl, body25 in BODY25_TO_SMPL.items():
        out[..., smpl, :] = keypoints[..., body25, :]
    return out


def keypoint_boxes(keypoints: np.ndarray, min_confidence: float = 0.1) -> np.ndarray:
    """``(..., 4)`` ``x0, y0, x1, y1`` of the confident keypoints ``(..., J, 3)`` (zeros when none)."""
    conf = keypoints[..., 2] > min_confidence
    lo = np.where(conf[..., None], keypoints[..., :2], np.inf).min(axis=-2)
    hi = np.where(conf[..., None], keypoints[..., :2], -np.inf).max(axis=-2)
    any_conf = conf.any(axis=-1)[..., None]
    return np.where(any_conf, np.concatenate([lo, hi], axis=-1), 0.0)


@dataclass(frozen=True)
class EditedClip:
    """An edited real video with 2D keypoints and cross-shot identities (no 3D ground truth).

    Attributes:
        name: the clip's name.
        source: ``"ava"`` or ``"sitcoms"``.
        frame_paths: ``(T,)`` image file of each frame (read on demand by :meth:`frames`).
        cut_frames: ``(C,)`` first frame of each new shot.
        fps: frames per second.
        person_ids: ``(P,)`` one id per person, the same across cuts where the data links them.
        keypoints_body25: ``(P, T, 25, 3)`` OpenPose ``u, v, confidence`` (0 where unobserved).
        keypoints2d: ``(P, T, 24, 3)`` the same in SMPL order (:func:`body25_to_smpl`).
        valid: ``(P, T)`` bool, the person is observed in that frame.
        bboxes: ``(P, T, 4)`` boxes of the confident keypoints.
        linked: ``(P,)`` bool, the person is observed on both sides of a cut (PCK* can score them).
        K: ``(T, 3, 3)`` per-frame intrinsics where the data gives them, else None.
        R: ``(T, 3, 3)`` world-to-camera rotations (the reconstruction's frame) or None.
        t: ``(T, 3)`` world-to-camera translations (the reconstruction's scale) or None.
        missing_hint: how to obtain the frames when they are not on disk.
        metadata: JSON-ready description (source files, image names).
    """

    name: str
    source: str
    frame_paths: tuple[Path, ...]
    cut_frames: np.ndarray
    fps: float
    person_ids: np.ndarray
    keypoints_body25: np.ndarray
    keypoints2d: np.ndarray
    valid: np.ndarray
    bboxes: np.ndarray
    linked: np.ndarray
    K: np.ndarray | None = None
    R: np.ndarray | None = None
    t: np.ndarray | None = None
    missing_hint: str = ""
    metadata: dict[str, Any] = field(default_factory=dict)

    @property
    def num_frames(self) -> int:
        return len(self.frame_paths)

    def shots(self) -> Shots:
        """The clip's shot structure (ground-truth cuts)."""
        return Shots(self.cut_frames, self.fps, self.num_frames, np.zeros(self.num_frames), f"{self.source}:labels")

    def missing_frames(self) -> list[Path]:
        """Frame files that are not on disk."""
        return [p for p in self.frame_paths if not p.is_file()]

    def frames(self) -> Iterator[np.ndarray]:
        """RGB frames in order; InputError naming the first missing file (and how to get it) before any is read."""
        missing = self.missing_frames()
        if missing:
            raise InputError(f"{missing[0]}: frame not present ({len(missing)} of {self.num_frames} missing; "
                             f"{self.missing_hint})")
        for path in self.frame_paths:
            yield read_rgb(path)


# ---------------------------------------------------------------- AVA

@dataclass(frozen=True)
class AvaBoxes:
    """Rows of an AVA v2.2 annotation csv.

    Attributes:
        video_ids: ``(N,)`` str.
        seconds: ``(N,)`` int timestamp (s).
        boxes: ``(N, 4)`` ``x1, y1, x2, y2`` normalised to [0, 1].
        action_ids: ``(N,)`` int.
        person_ids: ``(N,)`` int, links boxes of one person across nearby seconds (not across shots).
    """

    video_ids: np.ndarray
    seconds: np.ndarray
    boxes: np.ndarray
    action_ids: np.ndarray
    person_ids: np.ndarray


def load_ava_boxes(path: str | Path) -> AvaBoxes:
    """Read ``ava_{train,val}_v2.2.csv`` (no header; 8 columns)."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: missing AVA annotation csv")
    vids, secs, boxes, actions, persons = [], [], [], [], []
    with open(path, newline="") as file:
        for line, row in enumerate(csv.reader(file), start=1):
            if not row:
                continue
            if len(row) != 8:
                raise InputError(f"{path} line {line}: expected 8 columns (video_id, sec, x1, y1, x2, y2, "
                                 f"action_id, person_id), got {len(row)}")
            try:
                vids.append(row[0])
                secs.append(int(row[1]))
                boxes.append([float(v) for v in row[2:6]])
                actions.append(int(row[6]))
                persons.append(int(row[7]))
            except ValueError:
                raise InputError(f"{path} line {line}: a number field is not a number") from None
    box = np.asarray(boxes, dtype=np.float64).reshape(-1, 4)
    if box.size and (box.min() < 0 or box.max() > 1):
        raise InputError(f"{path}: boxes must be normalised to [0, 1]")
    return AvaBoxes(np.asarray(vids, dtype=str), np.asarray(secs, np.int64), box, np.asarray(actions, np.int64),
                    np.asarray(persons, np.int64))


def _ava_frame_path(root: Path, imgname: str) -> Path:
    """Where an npz's ``imgname`` lives: as given (absolute or under the root), else under
    ``{train,val}/{midframes,allframes}/<video>/<file>``."""
    given = Path(imgname)
    for candidate in (given, root / given):
        if candidate.is_file():
            return candidate
    if len(given.parts) >= 2:
        video, file = given.parts[-2], given.parts[-1]
        for split in ("val", "train"):
            for kind in ("midframes", "allframes"):
                candidate = root / split / kind / video / file
                if candidate.is_file():
                    return candidate
    return given if given.is_absolute() else root / given


def load_ava_clip(root: str | Path, npz_path: str | Path, fps: float | None = None) -> EditedClip:
    """One AVA clip from a Multishot ``process_phalp.py`` npz (one person followed across a shot change).

    Args:
        root: the AVA root (frames are looked for under it).
        npz_path: the clip's npz (``imgname (T,)``, ``shot (T,)``, ``body_keypoints (T, 25, 3)`` or
            ``body_keypoints_2d``, optional ``valid (T,)``).
        fps: frames per second; default 1 for ``midframes`` names (``0902.jpg``), 25 for ``allframes``
            names (``0902_03.jpg``).
    """
    root, npz_path = Path(root), Path(npz_path)
    if not npz_path.is_file():
        raise InputError(f"{npz_path}: missing AVA clip npz")
    try:
        with np.load(npz_path, allow_pickle=False) as data:
            arrays = {k: data[k] for k in data.files}
    except Exception as error:  # zipfile/numpy raise many types for a broken file
        raise InputError(f"{npz_path}: not a readable npz ({type(error).__name__})") from None
    key = "body_keypoints" if "body_keypoints" in arrays else "body_keypoints_2d"
    for needed in ("imgname", "shot", key):
        if needed not in arrays:
            raise InputError(f"{npz_path}: missing field {needed!r} (expected the Multishot process_phalp.py output)")
    names = [str(n) for n in arrays["imgname"].reshape(-1)]
    t = len(names)
    shot = np.asarray(arrays["shot"]).reshape(-1).astype(np.int64)
    keypoints = np.asarray(arrays[key], dtype=np.float64)
    if shot.shape != (t,) or keypoints.shape != (t, BODY25, 3):
        raise InputError(f"{npz_path}: expected shot ({t},) and {key} ({t}, 25, 3), got {shot.shape} and {keypoints.shape}")
    if np.any(np.diff(shot) < 0):
        raise InputError(f"{npz_path}: shot labels must not decrease, got {shot.tolist()}")
    valid = np.asarray(arrays.get("valid", np.ones(t)), dtype=np.float64).reshape(-1) > 0
    if valid.shape != (t,):
        raise InputError(f"{npz_path}: valid must have {t} entries, got {valid.shape}")
    cuts = np.flatnonzero(np.diff(shot) != 0) + 1
    if fps is None:
        fps = AVA_ALLFRAMES_FPS if "_" in Path(names[0]).stem else AVA_MIDFRAMES_FPS
    kp = np.where(valid[:, None, None], keypoints, 0.0)[None]
    valid = valid[None]
    linked = np.array([bool(cuts.size) and all(valid[0, :c].any() and valid[0, c:].any() for c in cuts)])
    return EditedClip(
        name=npz_path.stem, source="ava", frame_paths=tuple(_ava_frame_path(root, n) for n in names),
        cut_frames=cuts.astype(np.int64), fps=float(fps), person_ids=np.zeros(1, np.int64), keypoints_body25=kp,
        keypoints2d=body25_to_smpl(kp), valid=valid, bboxes=keypoint_boxes(kp), linked=linked,
        missing_hint="AVA frames come from the CVDF mirror: run the Multishot repository's prepare_ava.py",
        metadata={"source_file": npz_path.name, "imgname": names, "seqname": str(arrays["seqname"].reshape(-1)[0])
                  if "seqname" in arrays and arrays["seqname"].size else None})


def find_ava_clips(root: str | Path) -> list[Path]:
    """Clip npz files under an AVA root (those holding ``shot`` labels), sorted."""
    found = []
    for path in sorted(Path(root).rglob("*.npz")):
        try:
            with np.load(path, allow_pickle=False) as data:
                if "shot" in data.files and "imgname" in data.files:
                    found.append(path)
        except Exception:  # not an npz of ours: ignore while listing
            continue
    return found


def describe_ava(root: str | Path) -> dict[str, Any]:
    """Annotation csvs, frame folders and clips under an AVA root."""
    root = Path(root)
    csvs = sorted([*root.glob("ava_*_v2.2.csv"), *root.glob("annotations/ava_*_v2.2.csv")])
    annotations = []
    for path in csvs:
        boxes = load_ava_boxes(path)
        annotations.append({"file": path.relative_to(root).as_posix(), "rows": int(len(boxes.seconds)),
                            "videos": int(len(set(boxes.video_ids.tolist()))),
                            "seconds": int(len(set(zip(boxes.video_ids.tolist(), boxes.seconds.tolist()))))})
    frames = {}
    for split in ("train", "val"):
        for kind in ("midframes", "allframes"):
            folder = root / split / kind
            if folder.is_dir():
                frames[f"{split}/{kind}"] = {"videos": sum(1 for p in folder.iterdir() if p.is_dir()),
                                             "images": sum(1 for _ in folder.glob("*/*.jpg"))}
    clips = []
    for path in find_ava_clips(root):
        clip = load_ava_clip(root, path)
        clips.append({"name": clip.name, "file": path.relative_to(root).as_posix(), "frames": clip.num_frames,
                      "cuts": clip.cut_frames.tolist(), "people": int(len(clip.person_ids)),
                      "frames_present": clip.num_frames - len(clip.missing_frames())})
    return {"annotations": annotations, "frames": frames, "clips": clips}


# ---------------------------------------------------------------- sitcoms

def sitcom_locations(root: str | Path) -> list[str]:
    """Locations with both ``human_data/<loc>.json`` and ``human_pairs/<loc>.json``."""
    root = Path(root)
    return sorted(p.stem for p in (root / "human_data").glob("*.json") if (root / "human_pairs" / p.name).is_file())


def _openpose(value, where: str) -> np.ndarray:
    try:
        kp = np.asarray(value, dtype=np.float64).reshape(-1, 3)
    except (TypeError, ValueError):
        raise InputError(f"{where}: openpose_keypoints are not (25, 3) numbers") from None
    if kp.shape != (BODY25, 3):
        raise InputError(f"{where}: expected OpenPose BODY_25 (25, 3) keypoints, got {kp.shape[0]} keypoints")
    return kp


def _sitcom_cameras(root: Path, location: str) -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    path = root / "sparse_reconstruction_and_nerf_data" / location / "cameras.json"
    if not path.is_file():
        return {}
    data = read_json(path)
    out = {}
    for k, frame in enumerate(data.get("frames", [])):
        try:
            K = np.asarray(frame["intrinsics"], dtype=np.float64)
            cam_to_world = np.asarray(frame["camtoworld"], dtype=np.float64)
            name = str(frame["image_name"])
        except KeyError as missing:
            raise InputError(f"{path} frames[{k}]: missing field {missing}") from None
        if K.shape != (3, 3) or cam_to_world.shape != (4, 4):
            raise InputError(f"{path} frames[{k}]: intrinsics must be 3x3 and camtoworld 4x4")
        world_to_cam = np.linalg.inv(cam_to_world)
        out[name] = (K, world_to_cam[:3, :3], world_to_cam[:3, 3])
    return out


def load_sitcom_pairs(root: str | Path, location: str) -> list[EditedClip]:
    """Two-frame clips (one per pair of images across a shot change) of one sitcom location."""
    root = Path(root)
    humans_path = root / "human_data" / f"{location}.json"
    pairs_path = root / "human_pairs" / f"{location}.json"
    humans, pairs = read_json(humans_path), read_json(pairs_path)
    if not isinstance(humans, dict):
        raise InputError(f"{humans_path}: expected {{image_name: [humans]}}")
    if not isinstance(pairs, list):
        raise InputError(f"{pairs_path}: expected a list of [img_a, idx_a, img_b, idx_b]")
    grouped: dict[tuple[str, str], list[tuple[int, int]]] = {}
    for k, pair in enumerate(pairs):
        if not (isinstance(pair, (list, tuple)) and len(pair) == 4):
            raise InputError(f"{pairs_path}[{k}]: expected [img_a, idx_a, img_b, idx_b], got {pair!r}")
        img_a, idx_a, img_b, idx_b = pair
        for img, idx in ((img_a, idx_a), (img_b, idx_b)):
            if img not in humans:
                raise InputError(f"{pairs_path}[{k}]: image {img!r} is not in {humans_path.name}")
            if not isinstance(idx, int) or not 0 <= idx < len(humans[img]):
                raise InputError(f"{pairs_path}[{k}]: {img} has no human {idx!r} ({len(humans[img])} humans)")
        grouped.setdefault((str(img_a), str(img_b)), []).append((int(idx_a), int(idx_b)))
    cameras = _sitcom_cameras(root, location)
    frame_dirs = [root / "images" / location, root / "sparse_reconstruction_and_nerf_data" / location / "images"]
    clips = []
    for (img_a, img_b), links in grouped.items():
        people = [(0, k) for k in range(len(humans[img_a]))]
        linked_b = {b: a for a, b in links}
        people += [(1, k) for k in range(len(humans[img_b])) if k not in linked_b]
        p = len(people)
        row_of = {person: r for r, person in enumerate(people)}
        kp = np.zeros((p, 2, BODY25, 3))
        valid = np.zeros((p, 2), bool)
        for frame, img in ((0, img_a), (1, img_b)):
            for k, human in enumerate(humans[img]):
                if "openpose_keypoints" not in human:
                    raise InputError(f"{humans_path} {img} human {k}: missing field 'openpose_keypoints'")
                row = row_of[(0, k)] if frame == 0 else row_of[(0, linked_b[k])] if k in linked_b else row_of[(1, k)]
                kp[row, frame] = _openpose(human["openpose_keypoints"], f"{humans_path} {img} human {k}")
                valid[row, frame] = True
        paths = []
        for img in (img_a, img_b):
            present = [d / img for d in frame_dirs if (d / img).is_file()]
            paths.append(present[0] if present else frame_dirs[0] / img)
        K = R = t = None
        if img_a in cameras and img_b in cameras:
            K, R, t = (np.stack([cameras[img_a][i], cameras[img_b][i]]) for i in range(3))
        clips.append(EditedClip(
            name=f"{location}:{Path(img_a).stem}|{Path(img_b).stem}", source="sitcoms", frame_paths=tuple(paths),
            cut_frames=np.array([1], np.int64), fps=SITCOM_FPS, person_ids=np.arange(p, dtype=np.int64),
            keypoints_body25=kp, keypoints2d=body25_to_smpl(kp), valid=valid, bboxes=keypoint_boxes(kp),
            linked=valid.all(axis=1), K=K, R=R, t=t,
            missing_hint=f"sitcom episodes are not distributed: dump the frames with ffmpeg into {frame_dirs[0]}",
            metadata={"location": location, "images": [img_a, img_b], "links": [list(x) for x in links]}))
    return clips


def describe_sitcoms(root: str | Path) -> dict[str, Any]:
    """Locations, annotated images, humans and cross-shot pairs under a sitcoms root."""
    root = Path(root)
    locations = sitcom_locations(root)
    if not locations:
        raise InputError(f"{root / 'human_pairs'}: missing (no location has both human_data/<loc>.json and "
                         f"human_pairs/<loc>.json)")
    out = []
    for loc in locations:
        humans = read_json(root / "human_data" / f"{loc}.json")
        clips = load_sitcom_pairs(root, loc)
        out.append({"location": loc, "images": len(humans), "humans": int(sum(len(v) for v in humans.values())),
                    "pairs": int(sum(len(c.metadata["links"]) for c in clips)), "clips": len(clips),
                    "frames_present": int(sum(c.num_frames - len(c.missing_frames()) for c in clips)),
                    "cameras": bool(_sitcom_cameras(root, loc))})
    return {"locations": out}


__all__ = ["AvaBoxes", "BODY25_TO_SMPL", "EditedClip", "body25_to_smpl", "describe_ava", "describe_sitcoms",
           "find_ava_clips", "keypoint_boxes", "load_ava_boxes", "load_ava_clip", "load_sitcom_pairs",
           "sitcom_locations"]
