"""Metrics that need no ground truth (docs/METRICS.md): cross-shot PCK*, Jitter and height-based foot sliding.

They read only a reconstruction: world joints ``(P, T, 24, 3)`` in metres, ``valid (P, T)``, its
cameras and the detector's 2D keypoints. Each returns :class:`Samples` so sequences pool.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from multithumbs.errors import InputError
from multithumbs.geometry import project_points
from multithumbs.metrics.alignment import MM_PER_M, Samples, ValidFrames, window_mask

SMPL_NUM_VERTICES = 6890
"""Vertices of the SMPL mesh; the foot vertices below index it."""

SMPL_FOOT_VERTICES = (3216, 3387, 6617, 6787)
"""SMPL vertices on the soles (left heel, left toe, right heel, right toe), as WHAM/GVHMR."""

FOOT_JOINTS = (7, 8, 10, 11)
"""SMPL ankle and foot joints: the foot points when the mesh is not SMPL's."""

SPINE_JOINTS = (0, 12)
"""Pelvis and neck: their difference is a body's up direction (used to estimate the world's up)."""


def foot_points(joints: np.ndarray, vertices: np.ndarray | None,
                foot_vertex_ids: Sequence[int] | np.ndarray | None = None) -> np.ndarray:
    """Foot points ``(..., F, 3)`` for foot sliding.

    Args:
        joints: ``(..., 24, 3)``.
        vertices: ``(..., V, 3)`` or None.
        foot_vertex_ids: the body model's foot vertices; when None, SMPL's four sole vertices if
            ``V = 6890``, else the ankle and foot joints.
    """
    if vertices is not None and foot_vertex_ids is not None:
        return vertices[..., np.asarray(foot_vertex_ids), :]
    if vertices is not None and vertices.shape[-2] == SMPL_NUM_VERTICES:
        return vertices[..., SMPL_FOOT_VERTICES, :]
    return joints[..., FOOT_JOINTS, :]


@dataclass(frozen=True)
class CrossShotPck:
    """PCK* samples of both directions across cuts.

    Attributes:
        forward: ``(C, P, J)`` 100 where joint of person ``p`` reconstructed at ``t_b - 1`` and projected
            with the camera of ``t_b`` lands within the threshold of the keypoint observed at ``t_b``, else 0.
        backward: ``(C, P, J)`` the same from ``t_b`` into ``t_b - 1``.
    """

    forward: Samples
    backward: Samples

    def percentage(self) -> float:
        """Mean of the two directions' percentages (the one that has samples when the other has none)."""
        return mean_of_directions(self.forward.mean(), self.backward.mean())


def mean_of_directions(forward: float, backward: float) -> float:
    """Mean of two directions' PCK percentages, ignoring a direction without samples (NaN)."""
    both = [v for v in (forward, backward) if not np.isnan(v)]
    return float(np.mean(both)) if both else float("nan")


def cross_shot_pck(joints: np.ndarray, valid: np.ndarray, keypoints2d: np.ndarray, K: np.ndarray,
                   R: np.ndarray, t: np.ndarray, cut_frames: Sequence[int] | np.ndarray,
                   alpha: float = 0.1, min_confidence: float = 0.5) -> CrossShotPck:
    """Cross-shot PCK (Pavlakos et al. 2022) of a reconstruction.

    At each cut ``(t_b - 1, t_b)`` and for every person valid on both sides: the 3D joints of one side
    are projected with the estimated camera of the other side and compared with the keypoints observed
    there. A joint is correct within ``alpha * max(w, h)`` of the keypoint, where ``w, h`` is the box of
    that person's confident keypoints in the observed frame (detector-only, so independent of the
    reconstruction). Only keypoints with confidence above ``min_confidence`` count.

    Args:
        joints: ``(P, T, 24, 3)`` world joints.
        valid: ``(P, T)`` bool.
        keypoints2d: ``(P, T, 24, 3)`` pixel ``u, v``, confidence, SMPL order.
        K: ``(T, 3, 3)``.
        R: ``(T, 3, 3)`` world-to-camera.
        t: ``(T, 3)``.
        cut_frames: ``(C,)``.
        alpha: threshold as a fraction of the box size.
        min_confidence: keypoints at or below this confidence are left out.
    Returns:
        both directions' samples.
    """
    if keypoints2d.shape[:3] != joints.shape[:3] or keypoints2d.shape[-1] != 3:
        raise InputError(f"keypoints2d: expected shape {(*joints.shape[:3], 3)} (SMPL-order keypoints "
                         f"matching the joints), got {keypoints2d.shape}")
    cuts = np.asarray(cut_frames, dtype=np.int64)
    before, after = cuts - 1, cuts
    both = valid[:, before] & valid[:, after]  # (P, C)

    def direction(src: np.ndarray, dst: np.ndarray) -> Samples:
        # Joints of frame src (P, C, 24, 3) seen by the camera of frame dst.
        uv = project_points(joints[:, src], K[dst], R[dst], t[dst])  # (P, C, 24, 2)
        kp = keypoints2d[:, dst]
        confident = kp[..., 2] > min_confidence  # (P, C, J)
        lo = np.where(confident[..., None], kp[..., :2], np.inf).min(axis=-2)
        hi = np.where(confident[..., None], kp[..., :2], -np.inf).max(axis=-2)
        size = np.where(confident.any(axis=-1), (hi - lo).max(axis=-1), 0.0)  # (P, C)
        hit = np.linalg.norm(uv - kp[..., :2], axis=-1) <= alpha * size[..., None]
        mask = confident & (both & (size > 0))[..., None]
        return Samples((100.0 * hit).transpose(1, 0, 2), mask.transpose(1, 0, 2))

    return CrossShotPck(direction(before, after), direction(after, before))


def jitter(joints: np.ndarray, valid: np.ndarray, fps: float,
           cut_frames: Sequence[int] | np.ndarray = (), include_cuts: bool = True) -> Samples:
    """Jitter (GVHMR ``compute_jitter``): mean norm of the third difference times ``fps^3``, in 10 m/s^3.

    Per person, over its valid frames in order (compressed, as GVHMR's masking does): every four
    consecutive compressed frames make a window.

    Args:
        joints: ``(P, T, J, 3)`` world joints, metres.
        valid: ``(P, T)`` bool, frames to use.
        fps: frames per second.
        cut_frames: ``(C,)``.
        include_cuts: count windows whose first and last frame lie in different shots.
    Returns:
        ``(P, T - 3)`` samples over packed windows (mean over joints per window).
    """
    if not fps > 0:
        raise InputError(f"fps: must be positive, got {fps}")
    packing = ValidFrames.of(valid)
    joints = packing.pack(joints)
    mask = window_mask(packing.valid, 4, cut_frames, include_cuts, frames=packing.frames)
    if not mask.shape[-1]:
        return Samples(np.zeros(mask.shape), mask)
    jerk = (joints[:, 3:] - 3.0 * joints[:, 2:-1] + 3.0 * joints[:, 1:-2] - joints[:, :-3]) * fps ** 3
    return Samples(np.linalg.norm(jerk, axis=-1).mean(axis=-1) / 10.0, mask)


def estimate_up(joints: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """The world's ``(3,)`` unit up direction, estimated as the mean pelvis-to-neck direction of valid bodies.

    People in the footage mostly stand, so this recovers the up axis of an arbitrary reconstructed
    world frame. Raises :class:`InputError` when there is no valid body.
    """
    spine = joints[..., SPINE_JOINTS[1], :] - joints[..., SPINE_JOINTS[0], :]
    spine = spine[valid]
    if not len(spine):
        raise InputError("valid: no valid body to estimate the world's up direction from")
    spine = spine / np.maximum(np.linalg.norm(spine, axis=-1, keepdims=True), np.finfo(float).tiny)
    up = spine.mean(axis=0)
    return up / np.linalg.norm(up)


def foot_sliding(feet: np.ndarray, valid: np.ndarray, up: np.ndarray,
                 cut_frames: Sequence[int] | np.ndarray = (), contact_height: float = 0.05,
                 ground_percentile: float = 5.0) -> Samples:
    """Foot sliding without ground truth, mm/frame: horizontal displacement of feet that touch the ground.

    Per person, the ground height is a low percentile of its foot heights over valid frames; a foot
    point is in contact over a frame pair when it is within ``contact_height`` of that ground in both
    frames. Pairs across a cut are excluded.

    Args:
        feet: ``(P, T, F, 3)`` world foot points, metres.
        valid: ``(P, T)`` bool.
        up: ``(3,)`` the world's up direction (unit).
        cut_frames: ``(C,)``.
        contact_height: metres above the ground that still count as contact.
        ground_percentile: percentile of the foot heights taken as the ground.
    Returns:
        ``(P, T - 1, F)`` samples.
    """
    up = np.asarray(up, dtype=np.float64)
    up = up / np.linalg.norm(up)
    height = feet @ up  # (P, T, F)
    pairs = window_mask(valid, 2, cut_frames, include_cuts=False)  # (P, T-1)
    ground = np.zeros(valid.shape[0])
    for p in np.nonzero(valid.any(axis=1))[0]:
        ground[p] = np.percentile(height[p, valid[p]], ground_percentile)
    low = (height - ground[:, None, None]) < contact_height
    step = np.diff(feet, axis=1)
    horizontal = step - (step @ up)[..., None] * up
    contact = pairs[..., None] & low[:, :-1] & low[:, 1:]
    return Samples(np.linalg.norm(horizontal, axis=-1) * MM_PER_M, contact)
