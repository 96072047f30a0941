"""Per-shot tracks written as a 4DHumans / PHALP results file, the way upstream writes one.

What upstream writes, with the source it comes from (brjathu/PHALP unless said otherwise):

* keys ``outputs//_DEMO/<video>/img/%06d.jpg`` numbered from 1 (``phalp/utils/utils.py:176``); only frames
  below ``video.end_frame`` (1300, ``phalp/configs/base.py:17``); every frame has ``time`` (0-based),
  ``shot`` and ``frame_path`` (``phalp/trackers/PHALP.py:208``); ``shot`` is 1 only at cuts PHALP's own
  PySceneDetect found, which is off by default (``detect_shots``, ``base.py:139``);
* per entry (``PHALP.py:441-468``): ``bbox`` ``[x, y, w, h]``; ``center``/``scale`` of the box padded to
  HMR2's 192:256 aspect; ``smpl`` rotation matrices; ``camera`` = ``pred_cam_t``; ``camera_bbox`` HMR2's
  weak-perspective ``(s, tx, ty)``; ``3d_joints`` (45, 3) SMPL joints without translation; ``2d_joints``
  those joints projected through HMR2's camera and divided by 256 (``phalp/models/hmar/hmar.py:119-131``);
  ``conf``, ``size``, ``mask`` (a one-element list of COCO RLE with str counts, ``PHALP.py:350-353``);
* tracks: DeepSORT's. A track is confirmed after ``n_init = 5`` consecutive hits and its first frames are
  then back-filled (``PHALP.py:232-244``); an unconfirmed track that misses a frame is dropped; a lost
  track stays listed for up to ``max_age_track = 50`` frames (``base.py:34-35``) with its last detection's
  stale values and ``tracked_time`` > 0, absent from ``tracked_ids``/``tracked_bbox`` (``PHALP.py:221-230``);
  ids count from 1.

What this writer cannot make: HMR2's 19 extra joints and its OpenPose face and foot points (mesh vertices):
their rows are 0 (the importer reads only the OpenPose joints that are SMPL joints, :mod:`.joints`); ``appe``,
``pose``, ``loca`` and ``uv`` (PHALP's networks) unless appearance codes are given. Detections are not
dropped by PHALP's 50x100 px size filter unless ``min_box`` says so, and a lost track that comes back after
more than 50 frames keeps its id (upstream would start a new one).
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path
from typing import Sequence

import numpy as np
import torch
from scipy.spatial.transform import Rotation

from multithumbs.errors import InputError
from multithumbs.geometry import reexpress_for_intrinsics
from multithumbs.io import publish
from multithumbs.perception.camera import HMR2_CROP_SIZE, HMR2_FOCAL_LENGTH, hmr2_intrinsics
from multithumbs.perception.joints import OPENPOSE25_TO_SMPL24, PHALP_NUM_JOINTS
from multithumbs.types import PersonTracks, Shots

HMR2_ASPECT = 192 / 256
"""Width over height of HMR2's input crop (4D-Humans pads every box to it before cropping)."""
N_INIT, MAX_AGE, END_FRAME = 5, 50, 1300
"""PHALP's defaults: hits to confirm a track, frames a lost track is kept, first frame not processed."""
_EMPTY_KEYS = ("tid", "bbox", "tracked_time", "tracked_ids", "tracked_bbox", "center", "scale", "size",
               "img_path", "img_name", "class_name", "conf", "annotations", "smpl", "camera", "camera_bbox",
               "3d_joints", "2d_joints", "mask", "extra_data")


def mask_box(mask: np.ndarray) -> np.ndarray:
    """``(4,)`` ``x0, y0, x1, y1`` box of a boolean ``(H, W)`` mask (pixel edges), zeros when empty."""
    ys, xs = np.nonzero(mask)
    if xs.size == 0:
        return np.zeros(4)
    return np.array([xs.min() - 0.5, ys.min() - 0.5, xs.max() + 0.5, ys.max() + 0.5])


def padded_box(box: np.ndarray, aspect: float = HMR2_ASPECT) -> tuple[np.ndarray, np.ndarray]:
    """``center (2,)`` and ``scale (2,)`` (width, height) of a continuous ``x0, y0, x1, y1`` box grown to
    ``aspect`` about its centre, as 4D-Humans' ``expand_bbox_to_aspect_ratio`` pads PHALP's boxes."""
    x0, y0, x1, y1 = np.asarray(box, dtype=np.float64)
    w, h = x1 - x0, y1 - y0
    w, h = (w, w / aspect) if w > h * aspect else (h * aspect, h)
    return np.array([(x0 + x1) / 2, (y0 + y1) / 2]), np.array([w, h])


def hmr2_projection(joints_cam: np.ndarray, focal_length: float = HMR2_FOCAL_LENGTH,
                    crop_size: int = HMR2_CROP_SIZE) -> np.ndarray:
    """``(..., N, 2)`` PHALP ``2d_joints`` of camera-frame joints in HMR2's camera (``camera`` added):
    focal ``F / R`` in units of the padded square, principal point at its centre, plus 0.5, so
    ``hmar.py:126-131`` followed by the division by ``render.res`` (``PHALP.py``)."""
    j = np.asarray(joints_cam, dtype=np.float64)
    return focal_length / crop_size * j[..., :2] / np.maximum(j[..., 2:3], 1e-9) + 0.5


def weak_perspective(camera: np.ndarray, center: np.ndarray, scale: np.ndarray, image_size: tuple[int, int],
                     focal_length: float = HMR2_FOCAL_LENGTH, crop_size: int = HMR2_CROP_SIZE) -> np.ndarray:
    """``(3,)`` ``camera_bbox`` ``(s, tx, ty)``: the inverse of ``hmar.py:119-120`` for a ``camera``
    translation and the padded box ``center``/``scale`` in continuous pixels."""
    h, w = image_size
    side = max(h, w)
    ratio = crop_size / side
    centre = (np.asarray(center, float) + np.array([(side - w) // 2, (side - h) // 2])) * ratio
    x, y, z = np.asarray(camera, float)
    s = 2 * focal_length / (z * float(np.max(scale)) * ratio)
    return np.array([s, x - (centre[0] - crop_size / 2) * z / focal_length,
                     y - (centre[1] - crop_size / 2) * z / focal_length])


def confirmed_runs(frames: Sequence[int], n_init: int = N_INIT) -> list[int]:
    """The detection frames DeepSORT keeps for one person: from the first ``n_init`` consecutive hits on
    (an unconfirmed track that misses a frame is deleted), every later hit."""
    kept, tentative = [], []
    for f in sorted(int(f) for f in frames):
        if kept:
            kept.append(f)
            continue
        tentative = tentative + [f] if tentative and f == tentative[-1] + 1 else [f]
        if len(tentative) == n_init:
            kept = tentative
    return kept


def export_phalp(path: str | Path, tracks: Sequence[PersonTracks], shots: Shots, body,
                 boxes: Sequence[np.ndarray] | None = None, uv_appearance: Sequence[np.ndarray] | None = None,
                 video_name: str = "video", overwrite: bool = False, detect_shots: bool = False,
                 n_init: int = N_INIT, max_age: int = MAX_AGE, end_frame: int = END_FRAME,
                 min_box: tuple[float, float] = (0.0, 0.0)) -> Path:
    """Write per-shot tracks as PHALP writes its results (module docstring: each field's source).

    Args:
        path: the ``.pkl`` to write (joblib, compress 3, as ``PHALP.py:264``); atomic; an existing file is
            replaced only with ``overwrite``.
        tracks: per-shot tracks; ids shared across shots are one PHALP track; ``tid`` is the id + 1.
        shots: the video's shots; cuts are flagged in ``shot`` only with ``detect_shots``.
        body: body model posing the joints (``.joints``, ``.rest_pelvis``).
        boxes: per shot ``(P, T, 4)`` ``x0, y0, x1, y1`` integer-centred pixels (default: the mask's box).
        uv_appearance: per shot ``(P, T, D)`` codes written as ``appe``.
        n_init, max_age, end_frame: PHALP's ``n_init``, ``max_age_track`` and ``video.end_frame``.
        min_box: ``(w, h)`` detections smaller than this are dropped (PHALP: ``(50, 100)``, ``small_w/h``).

    ``camera`` is each track's pelvis re-expressed for HMR2's camera (:func:`hmr2_intrinsics`; the same
    pixel, the depth scaled by the focal ratio, :func:`multithumbs.geometry.reexpress_for_intrinsics`), as
    4DHumans reports it; the method converts the same point back.
    """
    import joblib
    from pycocotools import mask as mask_utils

    path = Path(path)
    if path.exists() and not overwrite:
        raise InputError(f"{path}: already exists (pass overwrite=True / --overwrite to replace it)")
    if not path.parent.is_dir():
        raise InputError(f"{path.parent}: output folder does not exist")
    if len(tracks) != shots.num_shots:
        raise InputError(f"tracks: {len(tracks)} track sets for {shots.num_shots} shots")
    h, w = tracks[0].image_size if tracks else (0, 0)
    n_frames = min(shots.num_frames, end_frame)
    names = [f"outputs//_DEMO/{video_name}/img/{f + 1:06d}.jpg" for f in range(n_frames)]
    cuts = set(shots.cut_frames.tolist()) if detect_shots else set()
    results = {name: {"time": f, "shot": int(f in cuts), "frame_path": name, **{k: [] for k in _EMPTY_KEYS},
                      **({"appe": []} if uv_appearance is not None else {})} for f, name in enumerate(names)}
    entries: dict[int, dict[int, dict]] = {}  # PHALP tid -> video frame -> entry
    for k, ((a, b), tr) in enumerate(zip(shots.ranges, tracks)):
        if tr.num_frames != b - a or tr.start_frame != a:
            raise InputError(f"shot {k}: tracks cover frames {tr.start_frame}..{tr.start_frame + tr.num_frames - 1}"
                             f", the shot is {a}..{b - 1}")
        if not tr.valid.any():
            continue
        p, t = tr.valid.shape
        rest = body.rest_pelvis(tr.betas)[:, None]
        camera = reexpress_for_intrinsics(tr.transl + rest, tr.K, hmr2_intrinsics(tr.image_size)) - rest
        with torch.no_grad():
            joints = body.joints(tr.global_orient, tr.body_pose,
                                 np.broadcast_to(tr.betas[:, None], (p, t, 10))).double().numpy()
        orient = Rotation.from_rotvec(tr.global_orient.reshape(-1, 3)).as_matrix().reshape(p, t, 1, 3, 3)
        pose = Rotation.from_rotvec(tr.body_pose.reshape(-1, 3)).as_matrix().reshape(p, t, 23, 3, 3)
        for i, j in zip(*np.nonzero(tr.valid)):
            f = a + int(j)
            if f >= n_frames:
                continue
            mask = tr.mask(int(i), int(j))
            x0, y0, x1, y1 = (boxes[k][i, j] if boxes is not None else mask_box(mask)) + 0.5  # continuous
            if x1 - x0 < min_box[0] or y1 - y0 < min_box[1]:
                continue
            rles = mask_utils.encode(np.asfortranarray(mask[:, :, None].astype(np.uint8)))
            for rle in rles:
                rle["counts"] = rle["counts"].decode("utf-8")
            op = np.zeros((PHALP_NUM_JOINTS, 3))  # HMR2's joint order: OpenPose 25, 19 extra, 1 zero row
            for o, s in OPENPOSE25_TO_SMPL24.items():
                op[o] = joints[i, j, s]
            flat = np.where(np.isin(np.arange(PHALP_NUM_JOINTS), list(OPENPOSE25_TO_SMPL24))[:, None],
                            hmr2_projection(op + camera[i, j]), 0.0).reshape(-1)
            center, scale = padded_box([x0, y0, x1, y1])
            bbox = np.array([x0, y0, x1 - x0, y1 - y0], np.float32)
            entry = {"bbox": bbox, "center": center.astype(np.float32), "scale": scale.astype(np.float32),
                     "size": [h, w], "img_path": names[f], "img_name": Path(names[f]).name, "class_name": 0,
                     "conf": np.float32(1.0), "annotations": [], "extra_data": None,
                     "smpl": {"global_orient": orient[i, j].astype(np.float32),
                              "body_pose": pose[i, j].astype(np.float32), "betas": tr.betas[i].astype(np.float32)},
                     "camera": camera[i, j].astype(np.float32),
                     "camera_bbox": weak_perspective(camera[i, j], center, scale, (h, w)).astype(np.float32),
                     "3d_joints": op.astype(np.float32), "2d_joints": flat.astype(np.float32), "mask": rles}
            if uv_appearance is not None:
                entry["appe"] = np.asarray(uv_appearance[k][i, j], np.float32)
            entries.setdefault(int(tr.track_ids[i]) + 1, {})[f] = entry
    for tid in sorted(entries):
        hits = confirmed_runs(list(entries[tid]), n_init)
        for n, f in enumerate(hits):
            # Ghosts: until the next hit, or max_age frames, the track is listed with its last values.
            until = min(hits[n + 1] if n + 1 < len(hits) else n_frames, f + max_age + 1, n_frames)
            for g in range(f, until):
                frame = results[names[g]]
                frame["tid"].append(tid)
                frame["tracked_time"].append(g - f)
                for key, value in entries[tid][f].items():
                    frame[key].append(value)
                if g == f:
                    frame["tracked_ids"].append(tid)
                    frame["tracked_bbox"].append(entries[tid][f]["bbox"])
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    try:
        joblib.dump(results, tmp, compress=3)
        publish(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path
