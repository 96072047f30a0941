"""The multi-shot benchmark from multi-view captures: a small spec file -> a reproducible clip folder.

The paper switches camera at a cut: frames ``[0, t_1)`` from camera A, ``[t_1, t_2)`` from camera B,
... (:mod:`multithumbs.synth.splice`). A :class:`~multithumbs.datasets.clip_specs.ClipSpec` (JSON or TOML,
:mod:`multithumbs.datasets.clip_specs`) names the dataset, sequence, cameras (one per shot), cuts, frames and
people; anyone holding the data rebuilds the same clip.

The built clip folder holds what the synthetic scenes hold: ``video.mp4`` (undistorted pinhole frames
spliced from the cameras, :func:`multithumbs.synth.files.write_video`), ``ground_truth.npz``
(:func:`multithumbs.io.save_ground_truth`; the same spec and data give the same bytes) and ``spec.json`` (the spec,
canonical, written last: its presence marks a finished clip).

Ground truth (:class:`multithumbs.types.GroundTruth`): world SMPL parameters of the people, every
frame's pinhole camera (``K`` scaled to the output size), the dataset's joints projected as
``keypoints2d`` (confidence 1 where the joint is in front of the camera and inside the image), boxes of
the projected mesh (or joints, when the dataset stores no mesh), ``visible`` where at least
``min_visible_joints`` joints fall inside the image, and ``camera_ids`` indexing the spec's cameras.
Extras: ``joints`` (the dataset's world joints, which the metrics should prefer to a re-posed body
when the user's SMPL differs from the dataset's), ``frame_ids``, ``rig_K``/``rig_R``/``rig_t``.
"""

from __future__ import annotations

import json
import os
import tempfile
from dataclasses import replace
from pathlib import Path
from typing import Any, Iterator, Sequence

import cv2
import numpy as np

from multithumbs.datasets.clip_specs import ClipSpec, load_specs
from multithumbs.datasets.sequence import MultiViewSequence, PeopleSeries
from multithumbs.errors import InputError
from multithumbs.geometry import axis_angle_to_matrix, matrix_to_axis_angle
from multithumbs.io import publish, save_ground_truth
from multithumbs.types import GroundTruth, WorldResult

CLIP_FILES = ("video.mp4", "ground_truth.npz", "spec.json")
FOOT_JOINTS = (7, 8, 10, 11)
SPINE_JOINTS = (0, 12)


# ---------------------------------------------------------------- world levelling

def level_transform(joints: np.ndarray, valid: np.ndarray, vertices: np.ndarray | None = None,
                    floor_percentile: float = 2.0, min_spread: float = 0.1, max_tilt_deg: float = 30.0
                    ) -> tuple[np.ndarray, np.ndarray]:
    """A rigid ``x' = Q x + u`` taking a metric world to ``+z`` up with the floor at ``z = 0``.

    The floor is the plane through the people's ground contacts: the lowest point of every valid body
    (mesh vertex, else foot joint) along the bodies' mean pelvis-to-neck direction, fitted by least
    squares and refitted without outliers (a jump lifts the feet). When the contacts do not span a
    plane (one person standing still: spread below ``min_spread`` metres across two directions) or the
    plane's normal is more than ``max_tilt_deg`` from the bodies' up, up is the bodies' mean spine
    direction instead (people in these captures stand). The new ``x`` axis is the old ``x`` projected onto
    the floor (the old ``y`` when ``x`` is nearly vertical); the floor height is a low percentile of the
    contacts' heights. No horizontal shift.

    Args:
        joints: ``(P, T, 24, 3)`` world joints.
        valid: ``(P, T)`` bool.
        vertices: ``(P, T, V, 3)`` world mesh vertices, or None.
    Returns:
        ``Q (3, 3)`` rotation and ``u (3,)``.
    """
    if not valid.any():
        raise InputError("level: no person has ground truth in the clip, so the floor and up direction are unknown "
                         "(set level = false)")
    spine = joints[..., SPINE_JOINTS[1], :] - joints[..., SPINE_JOINTS[0], :]
    spine = spine[valid]
    spine = spine / np.maximum(np.linalg.norm(spine, axis=-1, keepdims=True), 1e-12)
    body_up = spine.mean(axis=0)
    body_up /= np.linalg.norm(body_up)
    points = (vertices[valid].astype(np.float64) if vertices is not None and vertices.shape[2]
              else joints[..., FOOT_JOINTS, :][valid])
    up = body_up
    for _ in range(3):  # the lowest points depend on the up direction: refine both together
        contacts = points[np.arange(len(points)), np.argmin(points @ up, axis=-1)]  # (N, 3)
        normal = _floor_normal(contacts, body_up, min_spread, max_tilt_deg)
        if normal is None:
            break
        up = normal
    contacts = points[np.arange(len(points)), np.argmin(points @ up, axis=-1)]
    axis_x = np.array([1.0, 0.0, 0.0])
    if abs(up @ axis_x) > 0.9:
        axis_x = np.array([0.0, 1.0, 0.0])
    x = axis_x - (axis_x @ up) * up
    x /= np.linalg.norm(x)
    Q = np.stack([x, np.cross(up, x), up])
    floor = float(np.percentile(contacts @ up, floor_percentile))
    return Q, np.array([0.0, 0.0, -floor])


def _floor_normal(contacts: np.ndarray, body_up: np.ndarray, min_spread: float, max_tilt_deg: float
                  ) -> np.ndarray | None:
    """Unit normal (towards ``body_up``) of the plane through ground contacts ``(N, 3)``, or None when they
    do not determine a plane or it tilts more than ``max_tilt_deg`` from ``body_up``."""
    if len(contacts) < 3:
        return None
    keep = np.ones(len(contacts), bool)
    for _ in range(2):  # fit, then refit without the contacts far from the plane (a jump lifts the feet)
        used = int(keep.sum())
        centre = contacts[keep].mean(axis=0)
        _, spread, vt = np.linalg.svd(contacts[keep] - centre, full_matrices=False)
        normal = vt[-1] * (1.0 if vt[-1] @ body_up >= 0 else -1.0)
        residual = np.abs((contacts - centre) @ normal)
        keep = residual <= 3.0 * max(1.4826 * float(np.median(residual[keep])), 0.01)
        if keep.sum() < 3:
            return None
    planar = spread[1] / np.sqrt(used) >= min_spread  # RMS extent along the plane's narrower direction
    return normal if planar and normal @ body_up >= np.cos(np.deg2rad(max_tilt_deg)) else None


def move_people(people: PeopleSeries, Q: np.ndarray, u: np.ndarray) -> PeopleSeries:
    """The same people after the world moves rigidly by ``x' = Q x + u`` (exact for any SMPL-like body).

    ``global_orient`` becomes ``Q R``; since SMPL rotates about the pelvis joint ``j`` and adds
    ``transl``, the pelvis sits at ``j + transl`` and the new ``transl = Q pelvis + u - j`` with
    ``j = pelvis - transl`` read from the stored joints (no body model needed).
    """
    valid = people.valid
    pelvis = people.joints[..., 0, :]
    rest_pelvis = pelvis - people.transl
    orient = matrix_to_axis_angle(Q @ axis_angle_to_matrix(people.global_orient))
    transl = pelvis @ Q.T + u - rest_pelvis
    joints = people.joints @ Q.T + u
    vertices = None if people.vertices is None else (people.vertices @ Q.T.astype(np.float32) + u.astype(np.float32))
    mask3 = valid[..., None]
    return replace(people, global_orient=np.where(mask3, orient, 0.0), transl=np.where(mask3, transl, 0.0),
                   joints=np.where(mask3[..., None], joints, 0.0), vertices=vertices)


def move_camera(R: np.ndarray, t: np.ndarray, Q: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """World-to-camera ``R (..., 3, 3)``, ``t (..., 3)`` re-expressed after ``x' = Q x + u`` (rigid)."""
    R_new = R @ Q.T
    return R_new, t - (R_new @ u[..., None])[..., 0]


def scaled_intrinsics(K: np.ndarray, from_size: tuple[int, int], to_size: tuple[int, int]) -> np.ndarray:
    """``K`` of an image resized from ``(H, W)`` to ``(H', W')`` (pixel centres at integers, as ``cv2.resize``)."""
    sy, sx = to_size[0] / from_size[0], to_size[1] / from_size[1]
    S = np.array([[sx, 0.0, 0.5 * sx - 0.5], [0.0, sy, 0.5 * sy - 0.5], [0.0, 0.0, 1.0]])
    return S @ K


# ---------------------------------------------------------------- ground truth

def clip_ground_truth(spec: ClipSpec, sequence: MultiViewSequence
                      ) -> tuple[GroundTruth, dict[str, np.ndarray], list[tuple[str, int]]]:
    """The clip's ground truth, its extras, and the ``(camera, sequence frame)`` of every clip frame."""
    indices = sequence.check_indices(spec.indices)
    from multithumbs.synth.splice import shot_camera_ids

    cams = [sequence.camera(name) for name in spec.cameras]
    names = list(dict.fromkeys(spec.cameras))  # distinct cameras, in order of first use
    rig = [sequence.camera(n) for n in names]
    camera_ids = shot_camera_ids(spec.num_frames, spec.cuts, [names.index(c.name) for c in cams])

    everyone = sequence.ground_truth(indices, spec.people, with_vertices=True)
    if spec.people is None:  # everyone with ground truth somewhere in the clip
        keep = np.flatnonzero(everyone.valid.any(axis=1))
        everyone = _select(everyone, keep)
    people = everyone
    Q, u = (level_transform(people.joints, people.valid, people.vertices) if spec.level
            else (np.eye(3), np.zeros(3)))
    people = move_people(people, Q, u)

    size = spec.image_size or rig[names.index(spec.cameras[0])].image_size
    rig_K = np.stack([scaled_intrinsics(c.K, c.image_size, size) for c in rig])
    rig_R, rig_t = move_camera(np.stack([c.R for c in rig]), np.stack([c.t for c in rig]), Q, u)
    K, R, t = rig_K[camera_ids], rig_R[camera_ids], rig_t[camera_ids]

    p, n = len(people.names), spec.num_frames
    valid = people.valid
    cam_joints = np.einsum("tij,ptkj->ptki", R, people.joints) + t[None, :, None]
    depth = cam_joints[..., 2]
    uv = ((cam_joints / np.maximum(depth, 1e-9)[..., None]) @ np.swapaxes(K, -1, -2)[None])[..., :2]
    h, w = size
    inside = (depth > 0.05) & (uv[..., 0] >= -0.5) & (uv[..., 0] <= w - 0.5) & (uv[..., 1] >= -0.5) \
        & (uv[..., 1] <= h - 0.5) & valid[..., None]
    keypoints = np.concatenate([np.where(valid[..., None, None], uv, 0.0), inside[..., None].astype(np.float64)], -1)

    from multithumbs.metrics.identity import projected_boxes

    if people.vertices is not None and people.vertices.shape[2] > 0:
        points_cam = np.einsum("tij,ptvj->ptvi", R, people.vertices.astype(np.float64)) + t[None, :, None]
    else:
        points_cam = cam_joints
    boxes, present = projected_boxes(points_cam, np.broadcast_to(K, (p, n, 3, 3)), size)
    visible = valid & present & (inside.sum(axis=-1) >= spec.min_visible_joints)
    boxes = np.where(visible[..., None], boxes, 0.0)

    betas = np.zeros((p, people.betas.shape[-1]))
    for i in range(p):
        if valid[i].any():
            betas[i] = people.betas[i, valid[i]].mean(axis=0)
    shots = len(spec.cuts) + 1
    id_map = np.array([[s, q, q] for s in range(shots) for q in range(p)], dtype=np.int64).reshape(-1, 3)
    fps = float(spec.fps) if spec.fps is not None else sequence.fps / spec.stride
    world = WorldResult(
        person_ids=np.arange(p, dtype=np.int64), global_orient=people.global_orient, body_pose=people.body_pose,
        betas=betas, transl=people.transl, valid=valid, K=K, R=R, t=t,
        cut_frames=np.asarray(spec.cuts, dtype=np.int64), fps=fps, image_size=size, id_map=id_map,
        keypoints2d=keypoints)
    metadata = {
        "kind": "dataset", "dataset": spec.dataset, "sequence": spec.sequence, "name": spec.name,
        "spec": spec.to_json(), "people": list(people.names), "genders": list(people.genders),
        "cameras": names, "alignment": sequence.alignment, "notes": list(sequence.notes),
        "world": "levelled: +z up, floor at z = 0 (from the bodies)" if spec.level else "the dataset's metric world",
        "level_transform": {"Q": Q.round(12).tolist(), "u": u.round(12).tolist()},
        "joints_source": "dataset" if sequence.dataset != "egobody" else "gendered SMPL forward pass",
    }
    truth = GroundTruth(world, boxes, visible, camera_ids, metadata)
    extras = {"joints": people.joints, "frame_ids": people.frame_ids, "rig_K": rig_K, "rig_R": rig_R, "rig_t": rig_t}
    frames = [(spec.cameras[int(np.searchsorted(spec.cuts, f, side="right"))], int(indices[f])) for f in range(n)]
    return truth, extras, frames


def _select(people: PeopleSeries, keep: np.ndarray) -> PeopleSeries:
    return PeopleSeries(
        tuple(people.names[k] for k in keep), people.frame_ids, people.global_orient[keep], people.body_pose[keep],
        people.betas[keep], people.transl[keep], people.joints[keep], people.valid[keep],
        tuple(people.genders[k] for k in keep), None if people.vertices is None else people.vertices[keep])


# ---------------------------------------------------------------- files

class SplicedFrames:
    """The clip's frames, decoded one at a time (a 4K multi-shot clip does not fit in memory).

    Quacks like the ``(T, H, W, 3)`` array :func:`multithumbs.synth.files.write_video` iterates over.
    """

    def __init__(self, sequence: MultiViewSequence, frames: Sequence[tuple[str, int]], size: tuple[int, int]):
        self.sequence, self.frames, self.size = sequence, list(frames), size
        self.shape = (len(self.frames), size[0], size[1], 3)

    def __len__(self) -> int:
        return len(self.frames)

    def __getitem__(self, k: int) -> np.ndarray:
        camera, index = self.frames[k]
        image = self.sequence.frame(camera, index, undistort=True)
        h, w = self.size
        if image.shape[:2] != (h, w):
            shrink = image.shape[0] > h or image.shape[1] > w
            image = cv2.resize(image, (w, h), interpolation=cv2.INTER_AREA if shrink else cv2.INTER_LINEAR)
        return image

    def __iter__(self) -> Iterator[np.ndarray]:
        return (self[k] for k in range(len(self)))


def _write_json(path: Path, data: Any) -> Path:
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w") as file:
            file.write(json.dumps(data, indent=2, sort_keys=True) + "\n")
        publish(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def clip_is_built(spec: ClipSpec, clip_dir: str | Path) -> bool:
    """The folder holds a finished clip of exactly this spec."""
    clip_dir = Path(clip_dir)
    if not all((clip_dir / name).is_file() for name in CLIP_FILES):
        return False
    try:
        return json.loads((clip_dir / "spec.json").read_text()) == spec.to_json()
    except (OSError, ValueError):
        return False


def build_clip(spec: ClipSpec, sequence: MultiViewSequence, out_dir: str | Path, overwrite: bool = False) -> Path:
    """Build one clip into ``out_dir / spec.name``: ``video.mp4``, ``ground_truth.npz``, ``spec.json``.

    Existing clip files are replaced only with ``overwrite``; ``spec.json`` is written last.
    """
    from multithumbs.synth.files import write_video

    if sequence.dataset != spec.dataset or sequence.name != spec.sequence:
        raise InputError(f"spec {spec.name!r}: wants {spec.dataset} {spec.sequence}, got {sequence.dataset} {sequence.name}")
    clip_dir = Path(out_dir) / spec.name
    existing = [n for n in CLIP_FILES if (clip_dir / n).exists()]
    if existing and not overwrite:
        raise InputError(f"{clip_dir / existing[0]}: already exists (pass --overwrite to replace it)")
    truth, extras, frames = clip_ground_truth(spec, sequence)
    try:
        clip_dir.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise InputError(f"{clip_dir}: cannot create the clip folder ({error.strerror})") from None
    (clip_dir / "spec.json").unlink(missing_ok=True)  # an unfinished clip has no spec.json
    write_video(clip_dir / "video.mp4", SplicedFrames(sequence, frames, truth.world.image_size), truth.world.fps)
    # Byte-reproducible: the arrays are computed deterministically, the metadata is sorted JSON and
    # numpy.savez's zip entries carry zipfile's fixed 1980-01-01 date (a test guards this).
    save_ground_truth(clip_dir / "ground_truth.npz", truth, extras)
    _write_json(clip_dir / "spec.json", spec.to_json())
    return clip_dir


def iter_benchmark(specs: Sequence[ClipSpec | str | Path], data_root: str | Path, out_dir: str | Path,
                   smpl_dir: str | Path | None = None, overwrite: bool = False, bodies=None
                   ) -> Iterator[tuple[str, Path]]:
    """Build a benchmark: yield ``(name, clip folder)`` for every spec, in order.

    A clip already built from the same spec is reused (so a scheduled run resumes); a folder holding a
    different clip is an error unless ``overwrite``. Specs may be :class:`ClipSpec` or spec file paths.

    Args:
        specs: the benchmark's specs.
        data_root: the dataset's root folder (the one ``multithumbs dataset list`` describes).
        out_dir: where clip folders go (``out_dir / spec.name``).
        smpl_dir: folder of the user's SMPL models (EgoBody needs gendered models).
        overwrite: rebuild clips whose folders hold something else.
        bodies: ``gender -> body model`` instead of ``smpl_dir`` (tests inject one).
    """
    from multithumbs.datasets.catalog import open_sequence

    resolved: list[ClipSpec] = []
    for item in specs:
        resolved.extend([item] if isinstance(item, ClipSpec) else load_specs([item]))
    names = [s.name for s in resolved]
    duplicate = next((n for n in names if names.count(n) > 1), None)
    if duplicate:
        raise InputError(f"specs: two specs are named {duplicate!r} (names are output folders)")
    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise InputError(f"{out}: cannot create the output folder ({error.strerror})") from None
    cache: dict[tuple[str, str], MultiViewSequence] = {}
    for spec in resolved:
        clip_dir = out / spec.name
        if clip_is_built(spec, clip_dir):
            yield spec.name, clip_dir
            continue
        key = (spec.dataset, spec.sequence)
        if key not in cache:
            cache.clear()  # one sequence at a time: specs of a sequence are usually listed together
            cache[key] = open_sequence(data_root, spec.dataset, spec.sequence, smpl_dir=smpl_dir, bodies=bodies)
        yield spec.name, build_clip(spec, cache[key], out, overwrite=overwrite)



__all__ = ["CLIP_FILES", "SplicedFrames", "build_clip", "clip_ground_truth", "clip_is_built", "iter_benchmark",
           "level_transform", "move_camera", "move_people", "scaled_intrinsics"]
