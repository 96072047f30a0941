"""Independent reference implementations of the WHAM/GVHMR protocol metrics, for the tests.

Written from the protocol as METRICS.md states it (WHAM ``lib/eval/eval_utils.py``, GVHMR
``hmr4d/utils/eval/eval_utils.py`` and ``compute_global_metrics``), one person at a time with plain
loops, and with evo's Umeyama (``evo.core.geometry.umeyama_alignment``) for every similarity fit, so
they share no code with ``multithumbs.metrics``: masked frames are dropped and the rest treated as
consecutive, world errors are cut into chunks of 100 of those frames, Accel is on pelvis-aligned
camera-frame joints times fps^2, Jitter is the third difference times fps^3 / 10, foot sliding takes
the raw predicted feet where the true feet move less than 1 cm.
"""

from __future__ import annotations

import numpy as np
from evo.core.geometry import umeyama_alignment

HIPS = [1, 2]


def _jpe(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``(F, J, 3)`` pairs to ``(F,)`` mean joint distances."""
    return np.sqrt(((a - b) ** 2).sum(axis=-1)).mean(axis=-1)


def world_errors(pred: np.ndarray, true: np.ndarray, valid: np.ndarray, chunk: int | None = 100,
                 first_two: bool = True) -> np.ndarray:
    """Per-frame W-MPJPE (``first_two``) or WA-MPJPE errors of every person, mm, concatenated.

    Args:
        pred, true: ``(P, T, J, 3)`` world joints, metres.
        valid: ``(P, T)`` bool.
        chunk: compressed frames per chunk; None for one chunk per track.
    """
    out = []
    for p in range(len(pred)):
        x, y = pred[p][valid[p]], true[p][valid[p]]
        length = len(x) if chunk is None else chunk
        for start in range(0, len(x), max(length, 1)):
            xs, ys = x[start:start + length], y[start:start + length]
            fit = slice(0, 2) if first_two else slice(None)
            rotation, translation, scale = umeyama_alignment(xs[fit].reshape(-1, 3).T, ys[fit].reshape(-1, 3).T,
                                                             with_scale=True)
            moved = scale * np.einsum("ij,fnj->fni", rotation, xs) + translation
            out.append(_jpe(moved, ys) * 1000.0)
    return np.concatenate(out) if out else np.zeros(0)


def accel_errors(pred_cam: np.ndarray, true_cam: np.ndarray, valid: np.ndarray, fps: float) -> np.ndarray:
    """Per-triplet Accel errors (WHAM/GVHMR), m/s^2, of every person's compressed valid frames."""
    out = []
    for p in range(len(pred_cam)):
        x, y = pred_cam[p][valid[p]], true_cam[p][valid[p]]
        x = x - x[:, HIPS].mean(axis=1, keepdims=True)
        y = y - y[:, HIPS].mean(axis=1, keepdims=True)
        if len(x) < 3:
            continue
        a_x = x[:-2] - 2 * x[1:-1] + x[2:]
        a_y = y[:-2] - 2 * y[1:-1] + y[2:]
        out.append(np.linalg.norm(a_x - a_y, axis=-1).mean(axis=-1) * fps ** 2)
    return np.concatenate(out) if out else np.zeros(0)


def jitter_values(pred: np.ndarray, valid: np.ndarray, fps: float) -> np.ndarray:
    """Per-window Jitter (GVHMR), 10 m/s^3, of every person's compressed valid frames."""
    out = []
    for p in range(len(pred)):
        x = pred[p][valid[p]]
        if len(x) < 4:
            continue
        jerk = (x[3:] - 3 * x[2:-1] + 3 * x[1:-2] - x[:-3]) * fps ** 3
        out.append(np.linalg.norm(jerk, axis=2).mean(axis=-1) / 10.0)
    return np.concatenate(out) if out else np.zeros(0)


def foot_sliding_values(pred_feet: np.ndarray, true_feet: np.ndarray, valid: np.ndarray,
                        threshold: float = 0.01) -> np.ndarray:
    """Foot sliding with truth (GVHMR), mm: raw predicted foot displacements where the true feet rest."""
    out = []
    for p in range(len(pred_feet)):
        x, y = pred_feet[p][valid[p]], true_feet[p][valid[p]]
        contact = np.linalg.norm(y[1:] - y[:-1], axis=-1) < threshold
        out.append(np.linalg.norm(x[1:] - x[:-1], axis=-1)[contact] * 1000.0)
    return np.concatenate(out) if out else np.zeros(0)
