"""The focal length from people's heights: standing people as vertical poles of one height on a common floor
(the last source :func:`multithumbs.scene.focal.estimate_focal` tries; its module docstring, 3).
"""

from __future__ import annotations

from typing import Sequence

import numpy as np
from scipy.optimize import least_squares

from multithumbs.errors import InputError
from multithumbs.scene.focal import FocalConfig, FocalEstimate, _in_range, focal_from_fov


FOOT_JOINTS, TOP_JOINTS = (7, 8), (16, 17)   # SMPL ankles and shoulders (every layout the project reads has them)
_BASE = np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]])  # a level camera looking along world +y (z up)


def _camera_rotation(pitch: float, roll: float) -> np.ndarray:
    """World-to-camera rotation of a camera pitched down by ``pitch`` and rolled by ``roll`` (radians)."""
    c, s = np.cos(pitch), np.sin(pitch)
    Rx = np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    c, s = np.cos(roll), np.sin(roll)
    Rz = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    return Rz @ Rx @ _BASE


def _pole_tops(params: np.ndarray, feet: np.ndarray, shot: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """Predicted top pixels ``(N, 2)`` of unit poles standing on the floor at the foot pixels ``feet (N, 2)``.

    ``params``: ``log f`` then per shot ``pitch, roll, camera height`` (pole heights).
    """
    f = np.exp(params[0])
    per = params[1:].reshape(-1, 3)
    out = np.empty_like(feet)
    for k in range(len(per)):
        sel = shot == k
        R = _camera_rotation(per[k, 0], per[k, 1])
        height = per[k, 2]
        rays = np.c_[(feet[sel] - centre) / f, np.ones(sel.sum())] @ R  # world directions R^T x
        lam = -height / np.where(rays[:, 2] < -1e-6, rays[:, 2], -1e-6)
        top = lam[:, None] * rays + np.array([0.0, 0.0, 1.0])  # relative to the camera centre
        cam = top @ R.T
        out[sel] = f * cam[:, :2] / np.maximum(cam[:, 2:], 1e-6) + centre
    return out


def pole_observations(tracks: Sequence, min_confidence: float = 0.5, step: int = 2
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Foot (mid-ankle) and top (mid-shoulder) pixels of every confident person-frame.

    Args:
        tracks: per shot :class:`~multithumbs.types.PersonTracks` with SMPL-order keypoints ``(P, T, 24, 3)``.
        step: every ``step``-th frame.
    Returns:
        ``feet (N, 2)``, ``tops (N, 2)`` and ``shot (N,)`` (index into ``tracks``).
    """
    feet, tops, shots = [], [], []
    for k, tr in enumerate(tracks):
        kp = np.asarray(tr.keypoints2d, np.float64)
        if kp.ndim != 4 or kp.shape[2] < 24 or kp.shape[3] != 3:
            raise InputError(f"shot {k}: keypoints2d: expected (P, T, 24, 3) SMPL-order keypoints, got {kp.shape}")
        kp = kp[:, ::step]
        joints = list(FOOT_JOINTS + TOP_JOINTS)
        ok = np.asarray(tr.valid)[:, ::step] & (kp[:, :, joints, 2] >= min_confidence).all(axis=2)
        foot = kp[:, :, list(FOOT_JOINTS), :2].mean(axis=2)[ok]
        top = kp[:, :, list(TOP_JOINTS), :2].mean(axis=2)[ok]
        upright = top[:, 1] < foot[:, 1] - 10  # the top above the foot (image y down)
        feet.append(foot[upright])
        tops.append(top[upright])
        shots.append(np.full(int(upright.sum()), k))
    if not feet:
        return np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0, int)
    return np.concatenate(feet), np.concatenate(tops), np.concatenate(shots)


def fit_poles(feet: np.ndarray, tops: np.ndarray, shot: np.ndarray, image_size: tuple[int, int],
              init_fovs_deg: Sequence[float] = (35.0, 60.0, 90.0)) -> list[tuple[float, float]]:
    """Focal lengths fitted to pole observations from each starting field of view: ``[(focal_px, cost)]``.

    Args:
        feet, tops: ``(N, 2)`` pixels; shot: ``(N,)`` shot index (one camera pose per shot, one focal length).
    """
    h, w = image_size
    centre = np.array([(w - 1) / 2, (h - 1) / 2])
    n_shots = int(shot.max()) + 1
    out = []
    for fov in init_fovs_deg:
        x0 = np.r_[np.log(focal_from_fov(w, fov)), np.tile([np.deg2rad(15.0), 0.0, 1.3], n_shots)]
        lower = np.r_[np.log(focal_from_fov(w, 170.0)), np.tile([-1.4, -0.8, 0.05], n_shots)]
        upper = np.r_[np.log(focal_from_fov(w, 3.0)), np.tile([1.4, 0.8, 50.0], n_shots)]
        sol = least_squares(lambda p: (_pole_tops(p, feet, shot, centre) - tops).ravel(), x0, bounds=(lower, upper),
                            loss="huber", f_scale=2.0, method="trf", max_nfev=400)
        out.append((float(np.exp(sol.x[0])), float(sol.cost)))
    return out


def focal_from_heights(tracks: Sequence, image_size: tuple[int, int], config: FocalConfig = FocalConfig()
                       ) -> tuple[FocalEstimate | None, str]:
    """The focal length from standing people (module docstring, 3), or None and why not."""
    feet, tops, shot = pole_observations(tracks)
    h, w = image_size
    people = sum(int(np.asarray(tr.valid).any(axis=1).sum()) for tr in tracks)
    if len(feet) < config.min_heights:
        return None, f"{len(feet)} confident person-frames"
    spread = float(np.percentile(feet[:, 1], 90) - np.percentile(feet[:, 1], 10)) / h
    if spread < config.min_depth_spread:
        return None, f"people at one depth ({people} tracks)"
    fits = fit_poles(feet, tops, shot, image_size, config.init_fovs_deg)
    best = min(fits, key=lambda fc: fc[1])
    agree = [f for f, c in fits if c <= best[1] * 1.01 + 1e-9]
    if max(agree) > 1.1 * min(agree) or not _in_range(best[0], w, config):
        return None, "heights do not pin the focal length down"
    return FocalEstimate(best[0], "heights", f"{len(feet)} person-frames"), ""
