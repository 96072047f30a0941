"""Joint layouts of the field's estimators mapped onto SMPL's 24 joints (:mod:`multithumbs.conventions`).

``PersonTracks.keypoints2d`` is ``(P, T, 24, 3)`` in SMPL order (``J = 24``). Estimators report other
layouts; a joint with no counterpart gets confidence 0 (and position 0) rather than a guess:

* ViTPose (COCO-17): hips, knees, ankles, shoulders, elbows and wrists are SMPL joints; the face points
  (nose, eyes, ears) are not the SMPL head joint, and the pelvis, spine, collars, feet and hands have
  no COCO counterpart. The method falls back to the mid-hip for the 2D root (``method.align``).
* 4DHumans/HMR2 (``2d_joints`` of PHALP's results): the first 25 of its 44 (+1 padding) joints are
  OpenPose BODY_25, whose body joints HMR2 takes straight from SMPL's joints (its ``smpl_to_openpose``
  map): mid-hip is the SMPL pelvis, neck is SMPL's neck, and so on. Face and foot points are mesh
  vertices, not SMPL joints, and the spine, collars, head, feet and hands are absent.
"""

from __future__ import annotations

import numpy as np

from multithumbs.conventions import NUM_JOINTS

COCO17_NAMES: tuple[str, ...] = (
    "nose", "left_eye", "right_eye", "left_ear", "right_ear", "left_shoulder", "right_shoulder",
    "left_elbow", "right_elbow", "left_wrist", "right_wrist", "left_hip", "right_hip", "left_knee",
    "right_knee", "left_ankle", "right_ankle",
)
"""COCO-17 keypoint order (ViTPose's output)."""

COCO17_TO_SMPL24: dict[int, int] = {
    11: 1, 12: 2, 13: 4, 14: 5, 15: 7, 16: 8,          # hips, knees, ankles
    5: 16, 6: 17, 7: 18, 8: 19, 9: 20, 10: 21,          # shoulders, elbows, wrists
}
"""COCO-17 index -> SMPL joint index, for the joints that are the same anatomical point."""

OPENPOSE25_TO_SMPL24: dict[int, int] = {
    8: 0,                                               # mid-hip = pelvis
    12: 1, 9: 2, 13: 4, 10: 5, 14: 7, 11: 8,            # hips, knees, ankles (OpenPose: L hip 12, R hip 9)
    1: 12,                                              # neck
    5: 16, 2: 17, 6: 18, 3: 19, 7: 20, 4: 21,           # shoulders, elbows, wrists (OpenPose: L 5-7, R 2-4)
}
"""OpenPose BODY_25 index -> SMPL joint index, as HMR2's ``smpl_to_openpose`` defines its body joints."""

PHALP_NUM_JOINTS = 45
"""Joints in PHALP's ``2d_joints``: HMR2's 44 (OpenPose 25 + 19 extra) plus one zero row PHALP appends."""


def _remap(keypoints: np.ndarray, mapping: dict[int, int]) -> np.ndarray:
    src = np.asarray(keypoints, dtype=np.float64)
    out = np.zeros((*src.shape[:-2], NUM_JOINTS, src.shape[-1]))
    for a, b in mapping.items():
        out[..., b, :] = src[..., a, :]
    return out


def coco17_to_smpl24(keypoints: np.ndarray) -> np.ndarray:
    """COCO-17 keypoints ``(..., 17, 3)`` (u, v, score) to SMPL order ``(..., 24, 3)``; unmapped joints are 0."""
    kp = np.asarray(keypoints)
    if kp.shape[-2:] != (17, 3):
        raise ValueError(f"expected COCO-17 keypoints (..., 17, 3), got {kp.shape}")
    return _remap(kp, COCO17_TO_SMPL24)


def openpose25_to_smpl24(keypoints: np.ndarray) -> np.ndarray:
    """OpenPose BODY_25 (or HMR2's 44/45 with BODY_25 first) ``(..., N>=25, C)`` to ``(..., 24, C)``."""
    kp = np.asarray(keypoints)
    if kp.shape[-2] < 25:
        raise ValueError(f"expected at least 25 OpenPose joints, got {kp.shape}")
    return _remap(kp, OPENPOSE25_TO_SMPL24)


def smpl24_to_openpose(keypoints: np.ndarray, num_joints: int = PHALP_NUM_JOINTS) -> np.ndarray:
    """Inverse of :func:`openpose25_to_smpl24` into ``(..., num_joints, C)``; joints it cannot fill are 0."""
    kp = np.asarray(keypoints, dtype=np.float64)
    out = np.zeros((*kp.shape[:-2], num_joints, kp.shape[-1]))
    for a, b in OPENPOSE25_TO_SMPL24.items():
        out[..., a, :] = kp[..., b, :]
    return out


BLAZEPOSE33_TO_SMPL24: dict[int, int] = {
    23: 1, 24: 2, 25: 4, 26: 5, 27: 7, 28: 8,          # hips, knees, ankles
    11: 16, 12: 17, 13: 18, 14: 19, 15: 20, 16: 21,     # shoulders, elbows, wrists
}
"""BlazePose landmark index -> SMPL joint index. BlazePose's hips, knees, ankles, shoulders, elbows and
wrists are those joints. It has no pelvis: the mid-point of its hips (MediaPipe's world origin) lies about
9 cm below SMPL's, so the pelvis is left out like COCO's (the method falls back to the mid-hip). Its
face, hand and foot points (heel, toe tip) are surface points, not SMPL joints, and are left out too."""

BLAZEPOSE_SMPL_JOINTS: tuple[int, ...] = tuple(sorted(BLAZEPOSE33_TO_SMPL24.values()))
"""The SMPL joints :func:`blazepose33_to_smpl24` fills."""


def blazepose33_to_smpl24(landmarks: np.ndarray) -> np.ndarray:
    """BlazePose's 33 landmarks ``(..., 33, C)`` to SMPL order ``(..., 24, C)``; unmapped joints are 0."""
    lm = np.asarray(landmarks, dtype=np.float64)
    if lm.shape[-2] != 33:
        raise ValueError(f"expected BlazePose's 33 landmarks (..., 33, C), got {lm.shape}")
    return _remap(lm, BLAZEPOSE33_TO_SMPL24)
