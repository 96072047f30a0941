"""Camera metric (docs/METRICS.md "ATE"): absolute trajectory error of the camera centres after Sim(3) alignment.

Agrees with evo's APE (translation part, ``align=True, correct_scale=True``). When the centres cannot
fix a rotation (static cameras per shot give at most two distinct centres: cross-covariance rank < 2),
the caller's joint-based alignment is used instead and the result says so.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from multithumbs.errors import InputError
from multithumbs.geometry import Similarity
from multithumbs.metrics.alignment import Samples, apply_similarity, fit_similarity

MIN_CENTRE_RANK = 2
"""Umeyama needs a cross-covariance of rank >= 2 (dimension - 1) to determine the rotation."""


@dataclass(frozen=True)
class TrajectoryError:
    """ATE of one camera trajectory.

    Attributes:
        errors: ``(T,)`` samples, per-frame distance between aligned predicted and true centres, metres.
        alignment: Sim(3) that maps predicted world points into the true world.
        fallback: True when the centres were degenerate and the given joint-based alignment was used.
        centre_rank: rank of the centres' cross-covariance (what decided the fallback).
    """

    errors: Samples
    alignment: Similarity
    fallback: bool
    centre_rank: int

    @property
    def rmse(self) -> float:
        """Root mean square error, metres."""
        return self.errors.rms()

    @property
    def mean(self) -> float:
        """Mean error, metres."""
        return self.errors.mean()


def centre_rank(pred_centres: np.ndarray, true_centres: np.ndarray, relative_tolerance: float = 1e-9) -> int:
    """Rank of the cross-covariance of centred ``(N, 3)`` trajectories (singular values above
    ``relative_tolerance`` times the largest; 0 when all centres coincide)."""
    x = pred_centres - pred_centres.mean(axis=0)
    y = true_centres - true_centres.mean(axis=0)
    singular = np.linalg.svd(y.T @ x / max(len(x), 1), compute_uv=False)
    if singular[0] <= np.finfo(np.float64).tiny:
        return 0
    return int((singular > relative_tolerance * singular[0]).sum())


def absolute_trajectory_error(pred_centres: np.ndarray, true_centres: np.ndarray,
                              valid: np.ndarray | None = None,
                              fallback_alignment: Similarity | None = None) -> TrajectoryError:
    """ATE: Umeyama Sim(3) of predicted onto true camera centres, then per-frame centre distances.

    Args:
        pred_centres: ``(T, 3)`` predicted camera centres ``C = -R^T t`` (prediction's world).
        true_centres: ``(T, 3)`` true camera centres.
        valid: ``(T,)`` bool frames to use; all when None.
        fallback_alignment: Sim(3) prediction -> truth to use when the centres are degenerate
            (the WA alignment fitted on all people's joints).
    Returns:
        the trajectory error.
    """
    pred_centres = np.asarray(pred_centres, dtype=np.float64)
    true_centres = np.asarray(true_centres, dtype=np.float64)
    if pred_centres.shape != true_centres.shape or pred_centres.ndim != 2 or pred_centres.shape[-1] != 3:
        raise InputError(f"pred_centres: expected (T, 3) like true_centres {true_centres.shape}, "
                         f"got {pred_centres.shape}")
    valid = np.ones(len(pred_centres), dtype=bool) if valid is None else np.asarray(valid, dtype=bool)
    if not valid.any():
        raise InputError("valid: no camera frame to evaluate")
    rank = centre_rank(pred_centres[valid], true_centres[valid])
    fallback = rank < MIN_CENTRE_RANK
    if fallback:
        if fallback_alignment is None:
            raise InputError(f"camera centres: degenerate (cross-covariance rank {rank} < {MIN_CENTRE_RANK}) "
                             "and no fallback alignment was given")
        alignment = fallback_alignment
    else:
        alignment, _ = fit_similarity(pred_centres, true_centres, valid)
    aligned = apply_similarity(alignment, pred_centres)
    return TrajectoryError(Samples(np.linalg.norm(aligned - true_centres, axis=-1), valid),
                           alignment, fallback, rank)
