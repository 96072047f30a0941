"""Pose metrics against ground truth (METRICS.md): W-MPJPE, WA-MPJPE, MPJPE, PA-MPJPE, MPVPE, Accel, FS.

Inputs are numpy arrays in metres: joints ``(P, T, 24, 3)``, vertices ``(P, T, V, 3)``, ``valid (P, T)``
(the frames to score). Every function returns :class:`Samples` in millimetres (Accel in mm/frame^2),
so sequences pool frame-weighted. The functions do not choose the coordinate frame: the caller passes
prediction and truth in a common one (:mod:`multithumbs.metrics.evaluate` says which).
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from multithumbs.errors import InputError
from multithumbs.metrics.alignment import (
    MM_PER_M, Samples, apply_similarity, apply_track_similarities, fit_similarity, pelvis,
    track_similarities, window_mask,
)


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
        chunk: re-align every ``chunk`` frames; None for the whole track.
    Returns:
        ``(P, T, 24, 3)`` aligned predicted joints.
    """
    _check_pair(pred_joints, true_joints, valid)
    sim, _ = track_similarities(pred_joints, true_joints, valid, "first_two" if first_two else "all", chunk)
    return apply_track_similarities(sim, pred_joints, chunk)


def w_mpjpe(pred_joints: np.ndarray, true_joints: np.ndarray, valid: np.ndarray,
            chunk: int | None = None) -> Samples:
    """World MPJPE with first-frames alignment, mm (WHAM/GVHMR W-MPJPE; ``chunk=100`` is W-MPJPE100).

    Per person (and chunk): Sim(3) fitted on the joints of the first two valid frames together,
    applied to the whole track (chunk), then the mean joint error of every valid frame.

    Args:
        pred_joints: ``(P, T, 24, 3)`` predicted world joints.
        true_joints: ``(P, T, 24, 3)`` true world joints.
        valid: ``(P, T)`` bool, frames to score (and to fit on).
        chunk: frames per re-alignment window, or None for the whole track.
    Returns:
        ``(P, T)`` samples.
    """
    aligned = world_aligned(pred_joints, true_joints, valid, first_two=True, chunk=chunk)
    return _point_error(aligned, true_joints, valid)


def wa_mpjpe(pred_joints: np.ndarray, true_joints: np.ndarray, valid: np.ndarray,
             chunk: int | None = None) -> Samples:
    """World MPJPE with whole-track alignment, mm: the Sim(3) is fitted on all valid frames (of the chunk).

    Args and returns as :func:`w_mpjpe`.
    """
    aligned = world_aligned(pred_joints, true_joints, valid, first_two=False, chunk=chunk)
    return _point_error(aligned, true_joints, valid)


def acceleration(points: np.ndarray) -> np.ndarray:
    """``a_t = x_{t-1} - 2 x_t + x_{t+1}``: ``(P, T, N, 3)`` to ``(P, T - 2, N, 3)``, centres ``t = 1..T-2``."""
    return points[:, :-2] - 2.0 * points[:, 1:-1] + points[:, 2:]


def accel_error(pred_joints: np.ndarray, true_joints: np.ndarray, valid: np.ndarray,
                cut_frames: Sequence[int] | np.ndarray = (), include_cuts: bool = True) -> Samples:
    """Acceleration error per triplet, mm/frame^2: mean over joints of ``||a_pred - a_true||``.

    Args:
        pred_joints: ``(P, T, 24, 3)`` world joints (aligned to the truth's frame by the caller).
        true_joints: ``(P, T, 24, 3)``.
        valid: ``(P, T)`` bool; a triplet counts when its three frames are valid.
        cut_frames: ``(C,)`` first frame of each new shot.
        include_cuts: count triplets that span a cut (where cut-blind methods fail).
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
                               cut_frames: Sequence[int] | np.ndarray = (),
                               contact_speed: float = 0.01) -> Samples:
    """Foot sliding with ground truth (WHAM/GVHMR), mm: predicted foot displacement where the true foot rests.

    Contact: the true foot point moves less than ``contact_speed`` metres between two consecutive
    valid frames of one shot; the sample is the predicted displacement of that point over that pair.

    Args:
        pred_feet: ``(P, T, F, 3)`` predicted foot points (world, aligned to the truth's frame).
        true_feet: ``(P, T, F, 3)`` true foot points.
        valid: ``(P, T)`` bool.
        cut_frames: ``(C,)``; pairs across a cut are excluded.
        contact_speed: metres per frame under which the true point is in contact.
    Returns:
        ``(P, T - 1, F)`` samples, one per foot point and frame pair.
    """
    _check_pair(pred_feet, true_feet, valid)
    pairs = window_mask(valid, 2, cut_frames, include_cuts=False)  # (P, T-1)
    true_step = np.linalg.norm(np.diff(true_feet, axis=1), axis=-1)  # (P, T-1, F)
    pred_step = np.linalg.norm(np.diff(pred_feet, axis=1), axis=-1)
    return Samples(pred_step * MM_PER_M, pairs[..., None] & (true_step < contact_speed))
