"""Pose metrics against ground truth (docs/METRICS.md): W-MPJPE, WA-MPJPE, MPJPE, PA-MPJPE, MPVPE, Accel, FS.

Inputs are numpy arrays in metres: joints ``(P, T, 24, 3)``, vertices ``(P, T, V, 3)``, ``valid (P, T)``
(the frames to score). Every function returns :class:`Samples` in millimetres, except :func:`accel`
(m/s^2, the field's unit) and :func:`accel_world` (mm/frame^2), so sequences pool frame-weighted. Where
the references (WHAM, GVHMR) mask invalid frames they drop them and treat the rest as consecutive;
the chunked world errors, :func:`accel` and :func:`foot_sliding_against_truth` do the same. The
functions do not choose the coordinate frame: the caller passes prediction and truth in a common one
(:mod:`multithumbs.metrics.evaluate` says which).
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from multithumbs.errors import InputError
from multithumbs.metrics.alignment import (
    MM_PER_M, Samples, ValidFrames, apply_similarity, apply_track_similarities, fit_similarity, pelvis,
    track_similarities, window_mask,
)

WORLD_CHUNK = 100
"""Valid frames per re-alignment chunk of the headline W-MPJPE / WA-MPJPE (WHAM/GVHMR's "100")."""


def _check_pair(pred: np.ndarray, true: np.ndarray, valid: np.ndarray) -> None:
    if pred.shape != true.shape:
        raise InputError(f"pred: shape {pred.shape} differs from the truth's {true.shape}")
    if valid.shape != pred.shape[:2]:
        raise InputError(f"valid: expected shape {pred.shape[:2]}, got {valid.shape}")


def _point_error(pred: np.ndarray, true: np.ndarray, valid: np.ndarray) -> Samples:
    """Mean point distance per frame, mm: ``(P, T, N, 3)`` pairs to ``(P, T)`` samples."""
    return Samples(np.linalg.norm(pred - true, axis=-1).mean(axis=-1) * MM_PER_M, valid)


def mpjpe(pred_joints: np.ndarray, true_joints: np.ndarray, valid: np.ndarray,
          root_align: bool = True) -> Samples:
    """Mean per-joint position error per frame, mm.

    Args:
        pred_joints: ``(P, T, 24, 3)``.
        true_joints: ``(P, T, 24, 3)``.
        valid: ``(P, T)`` bool, frames to score.
        root_align: subtract each body's pelvis (mean of the hips) first; False gives the absolute error.
    Returns:
        ``(P, T)`` samples.
    """
    _check_pair(pred_joints, true_joints, valid)
    if root_align:
        pred_joints = pred_joints - pelvis(pred_joints)[..., None, :]
        true_joints = true_joints - pelvis(true_joints)[..., None, :]
    return _point_error(pred_joints, true_joints, valid)


def mpvpe(pred_vertices: np.ndarray, true_vertices: np.ndarray, pred_joints: np.ndarray,
          true_joints: np.ndarray, valid: np.ndarray, root_align: bool = True) -> Samples:
    """Mean per-vertex position error per frame, mm; root alignment subtracts the joint pelvis.

    Args:
        pred_vertices: ``(P, T, V, 3)``.
        true_vertices: ``(P, T, V, 3)``.
        pred_joints: ``(P, T, 24, 3)``, for the pelvis.
        true_joints: ``(P, T, 24, 3)``.
        valid: ``(P, T)`` bool.
        root_align: subtract the pelvis first; False gives the absolute error.
    Returns:
        ``(P, T)`` samples.
    """
    _check_pair(pred_vertices, true_vertices, valid)
    if root_align:
        pred_vertices = pred_vertices - pelvis(pred_joints)[..., None, :]
        true_vertices = true_vertices - pelvis(true_joints)[..., None, :]
    return _point_error(pred_vertices, true_vertices, valid)


def pa_mpjpe(pred_joints: np.ndarray, true_joints: np.ndarray, valid: np.ndarray) -> Samples:
    """Procrustes-aligned MPJPE per frame, mm: a Sim(3) per frame maps the prediction onto the truth.

    Root alignment has no effect here (the similarity fits the translation), so there is no option.

    Args:
        pred_joints: ``(P, T, 24, 3)``.
        true_joints: ``(P, T, 24, 3)``.
        valid: ``(P, T)`` bool.
    Returns:
        ``(P, T)`` samples.
    """
    _check_pair(pred_joints, true_joints, valid)
    values = np.zeros(valid.shape)
    if valid.any():
        # Fit only the scored frames: the others may hold anything, even degenerate points.
        src, dst = pred_joints[valid], true_joints[valid]
        sim, _ = fit_similarity(src, dst)
        values[valid] = np.linalg.norm(apply_similarity(sim, src) - dst, axis=-1).mean(axis=-1) * MM_PER_M
    return Samples(values, valid)


def world_aligned(pred_joints: np.ndarray, true_joints: np.ndarray, valid: np.ndarray,
                  first_two: bool = False, chunk: int | None = None) -> np.ndarray:
    """Predicted world joints after the per-person (per-chunk) Sim(3) of W-MPJPE or WA-MPJPE.

    Args:
        pred_joints: ``(P, T, 24, 3)`` in the prediction's world frame.
        true_joints: ``(P, T, 24, 3)`` in the true world frame.
        valid: ``(P, T)`` bool, frames the fit may use.
        first_two: fit on the first two valid frames of each track/chunk (W-MPJPE) instead of all
            of them (WA-MPJPE).
        chunk: re-align every ``chunk`` valid frames (compressed, as WHAM/GVHMR); None for the whole track.
    Returns:
        ``(P, T, 24, 3)`` aligned predicted joints.
    """
    _check_pair(pred_joints, true_joints, valid)
    sim, _ = track_similarities(pred_joints, true_joints, valid, "first_two" if first_two else "all", chunk)
    return apply_track_similarities(sim, pred_joints, valid, chunk)


def w_mpjpe(pred_joints: np.ndarray, true_joints: np.ndarray, valid: np.ndarray,
            chunk: int | None = WORLD_CHUNK) -> Samples:
    """World MPJPE with first-frames alignment, mm: WHAM/GVHMR's W-MPJPE100 by default.

    Per person, its valid frames in order (compressed) are cut into chunks of ``chunk`` frames, the last
    one shorter; each chunk gets the Sim(3) fitted on the joints of its first two frames together
    (2 x 24 points), then every frame's mean joint error. ``chunk=None`` is one chunk for the whole
    track (``w_mpjpe_track``, stricter across cuts).

    Args:
        pred_joints: ``(P, T, 24, 3)`` predicted world joints.
        true_joints: ``(P, T, 24, 3)`` true world joints.
        valid: ``(P, T)`` bool, frames to score (and to fit on).
        chunk: valid frames per re-alignment chunk, or None for the whole track.
    Returns:
        ``(P, T)`` samples at the original frames.
    """
    aligned = world_aligned(pred_joints, true_joints, valid, first_two=True, chunk=chunk)
    return _point_error(aligned, true_joints, valid)


def wa_mpjpe(pred_joints: np.ndarray, true_joints: np.ndarray, valid: np.ndarray,
             chunk: int | None = WORLD_CHUNK) -> Samples:
    """World MPJPE with whole-chunk alignment, mm: WHAM/GVHMR's WA-MPJPE100 by default.

    As :func:`w_mpjpe`, but each chunk's Sim(3) is fitted on all of its frames; ``chunk=None`` gives
    ``wa_mpjpe_track``.
    """
    aligned = world_aligned(pred_joints, true_joints, valid, first_two=False, chunk=chunk)
    return _point_error(aligned, true_joints, valid)


def acceleration(points: np.ndarray) -> np.ndarray:
    """``a_t = x_{t-1} - 2 x_t + x_{t+1}``: ``(P, T, N, 3)`` to ``(P, T - 2, N, 3)``, centres ``t = 1..T-2``."""
    return points[:, :-2] - 2.0 * points[:, 1:-1] + points[:, 2:]


def accel(pred_joints_cam: np.ndarray, true_joints_cam: np.ndarray, valid: np.ndarray, fps: float) -> Samples:
    """Acceleration error as WHAM/GVHMR report it, m/s^2: pelvis-aligned camera-frame joints.

    Per person, the valid frames in order (compressed, as the references' masking does); every
    triplet of consecutive compressed frames gives ``mean_j ||a_pred - a_true|| * fps^2`` with
    ``a_t = x_{t-1} - 2 x_t + x_{t+1}``.

    Args:
        pred_joints_cam: ``(P, T, 24, 3)`` predicted joints in each frame's predicted camera.
        true_joints_cam: ``(P, T, 24, 3)`` true joints in each frame's true camera.
        valid: ``(P, T)`` bool, frames to use.
        fps: frames per second.
    Returns:
        ``(P, T - 2)`` samples over packed triplets (their order is not the video's).
    """
    _check_pair(pred_joints_cam, true_joints_cam, valid)
    if not fps > 0:
        raise InputError(f"fps: must be positive, got {fps}")
    packing = ValidFrames.of(valid)
    pred = packing.pack(pred_joints_cam - pelvis(pred_joints_cam)[..., None, :])
    true = packing.pack(true_joints_cam - pelvis(true_joints_cam)[..., None, :])
    mask = window_mask(packing.valid, 3)
    if not mask.shape[-1]:
        return Samples(np.zeros(mask.shape), mask)
    diff = acceleration(pred) - acceleration(true)
    return Samples(np.linalg.norm(diff, axis=-1).mean(axis=-1) * fps ** 2, mask)


def accel_world(pred_joints: np.ndarray, true_joints: np.ndarray, valid: np.ndarray,
                cut_frames: Sequence[int] | np.ndarray = (), include_cuts: bool = True) -> Samples:
    """Acceleration error of world joints, mm/frame^2: this project's ``accel_world``, not the field's Accel.

    Triplets of three consecutive valid frames (not compressed), by default also those that span a cut:
    that is where methods that ignore cuts fail.

    Args:
        pred_joints: ``(P, T, 24, 3)`` world joints (aligned to the truth's frame by the caller, e.g.
            with the whole-track WA similarity).
        true_joints: ``(P, T, 24, 3)``.
        valid: ``(P, T)`` bool; a triplet counts when its three frames are valid.
        cut_frames: ``(C,)`` first frame of each new shot.
        include_cuts: count triplets that span a cut.
    Returns:
        ``(P, T - 2)`` samples; sample ``i`` is the triplet centred on frame ``i + 1``.
    """
    _check_pair(pred_joints, true_joints, valid)
    mask = window_mask(valid, 3, cut_frames, include_cuts)
    if not mask.shape[-1]:
        return Samples(np.zeros(mask.shape), mask)
    diff = acceleration(pred_joints) - acceleration(true_joints)
    return Samples(np.linalg.norm(diff, axis=-1).mean(axis=-1) * MM_PER_M, mask)


def foot_sliding_against_truth(pred_feet: np.ndarray, true_feet: np.ndarray, valid: np.ndarray,
                               contact_speed: float = 0.01) -> Samples:
    """Foot sliding with ground truth (GVHMR ``compute_foot_sliding``), mm.

    Per person, the valid frames in order (compressed); a foot point is in contact over a pair of
    consecutive compressed frames when its TRUE position moves less than ``contact_speed`` metres; the
    sample is the displacement of the PREDICTED point, as predicted (not aligned), over that pair.
    Pairs across a cut are kept, as GVHMR keeps every pair.

    Args:
        pred_feet: ``(P, T, F, 3)`` predicted foot points in the prediction's world frame.
        true_feet: ``(P, T, F, 3)`` true foot points.
        valid: ``(P, T)`` bool.
        contact_speed: metres per frame under which the true point is in contact.
    Returns:
        ``(P, T - 1, F)`` samples over packed pairs, one per foot point.
    """
    _check_pair(pred_feet, true_feet, valid)
    packing = ValidFrames.of(valid)
    pairs = window_mask(packing.valid, 2)  # (P, T-1)
    true_step = np.linalg.norm(np.diff(packing.pack(true_feet), axis=1), axis=-1)  # (P, T-1, F)
    pred_step = np.linalg.norm(np.diff(packing.pack(pred_feet), axis=1), axis=-1)
    return Samples(pred_step * MM_PER_M, pairs[..., None] & (true_step < contact_speed))
