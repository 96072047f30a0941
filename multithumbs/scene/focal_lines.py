"""The focal length from straight edges of three orthogonal directions (the source ``lines`` that
:func:`multithumbs.scene.focal.estimate_focal` tries first; its module docstring, 1).

Rooms, sets and streets are mostly built along three orthogonal directions (a "Manhattan world"): floor
planks, wall corners, shelves, door and window frames. Their edges meet at three vanishing points
``v_k ~ K R e_k``, and because the directions are orthogonal, the vanishing points pin the focal length
down: with two of them finite, ``f^2 = -(v_1 - c) . (v_2 - c)`` (principal point ``c`` at the image
centre). Here every frame's line segments (OpenCV's LSD) vote for a camera rotation ``R`` and focal
length ``f``: RANSAC over a grid of focal lengths (two segments give a vanishing point, a third the
second direction), then a robust least-squares refinement of ``log f`` and ``R`` on the segments' angles to
their nearest vanishing point. A frame counts only when its refinement pins ``f`` down (the standard
deviation of ``log f`` below ``max_line_std``: a camera looking square at a wall, level, does not); the
video's estimate is the median over frames, kept when the frames agree.

A segment's residual is the sine of the angle between it and the line from its midpoint to the vanishing
point (``v`` homogeneous, so vanishing points at infinity need no special case), weighted by the square
root of its length.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from multithumbs.errors import InputError
from multithumbs.scene.focal import FocalConfig, FocalEstimate, _in_range, focal_from_fov


@dataclass(frozen=True)
class LineFocal:
    """One frame's focal length from its line segments.

    Attributes:
        focal_px: the focal length (pixels).
        log_std: the standard deviation of ``log f`` from the refinement (relative error, 1 sigma).
        inliers: segments within ``angle_deg`` of a vanishing point.
        rotation: ``(3, 3)`` camera-from-Manhattan-frame rotation (its columns are the three directions).
    """

    focal_px: float
    log_std: float
    inliers: int
    rotation: np.ndarray


def line_segments(gray: np.ndarray, min_length: float, max_segments: int) -> np.ndarray:
    """The longest straight segments of a grey image: ``(N, 4)`` rows ``x1, y1, x2, y2`` (pixels).

    Args:
        gray: ``(H, W)`` uint8 image.
        min_length: shortest segment kept (pixels).
        max_segments: at most this many, longest first.
    """
    gray = np.asarray(gray)
    if gray.ndim != 2 or gray.dtype != np.uint8:
        raise InputError(f"line_segments: expected an (H, W) uint8 grey image, got {gray.shape} {gray.dtype}")
    found = cv2.createLineSegmentDetector(cv2.LSD_REFINE_STD).detect(gray)[0]
    if found is None:
        return np.zeros((0, 4))
    seg = found.reshape(-1, 4).astype(np.float64)
    length = np.hypot(seg[:, 2] - seg[:, 0], seg[:, 3] - seg[:, 1])
    order = np.lexsort((seg[:, 1], seg[:, 0], -length))  # longest first; ties broken by position, stably
    order = order[length[order] >= min_length][:max_segments]
    return seg[order]


def _segment_geometry(seg: np.ndarray, centre: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Homogeneous lines ``(N, 3)``, midpoints ``(N, 2)`` and unit directions ``(N, 2)`` in centred pixel
    coordinates, and lengths ``(N,)``."""
    p1, p2 = seg[:, :2] - centre, seg[:, 2:] - centre
    lines = np.cross(np.c_[p1, np.ones(len(seg))], np.c_[p2, np.ones(len(seg))])
    lines /= np.linalg.norm(lines, axis=1, keepdims=True)
    d = p2 - p1
    length = np.linalg.norm(d, axis=1)
    return lines, 0.5 * (p1 + p2), d / length[:, None], length


def _angle_sines(directions: np.ndarray, f: np.ndarray | float, mid: np.ndarray, unit: np.ndarray) -> np.ndarray:
    """``(..., 3, N)`` sines of the angles between segments and the lines from their midpoints to the
    vanishing points of ``directions (..., 3, 3)`` (camera frame, one per row) at focal length ``f (...)``."""
    f = np.asarray(f, np.float64)[..., None, None]
    v = np.concatenate([directions[..., :2] * f, directions[..., 2:]], axis=-1)  # K d, centred coordinates
    wx = v[..., 0:1] - mid[:, 0] * v[..., 2:3]  # direction midpoint -> vanishing point (either sign)
    wy = v[..., 1:2] - mid[:, 1] * v[..., 2:3]
    norm = np.maximum(np.hypot(wx, wy), 1e-12)
    return np.abs(unit[:, 0] * wy - unit[:, 1] * wx) / norm


def _hypotheses(lines: np.ndarray, f: float, samples: np.ndarray) -> np.ndarray:
    """``(S, 3, 3)`` orthonormal direction triples (rows, camera frame): segments ``a, b`` meet at the first
    vanishing point; the second direction is orthogonal to it and on segment ``c``'s interpretation plane."""
    a, b, c = lines[samples[:, 0]], lines[samples[:, 1]], lines[samples[:, 2]]
    scale = np.array([f, f, 1.0])
    vp = np.cross(a, b)
    d1 = vp / scale  # K^-1 v
    d2 = np.cross(d1, c * scale)  # orthogonal to d1 and to segment c's plane normal K^T l
    d1 /= np.maximum(np.linalg.norm(d1, axis=1, keepdims=True), 1e-12)
    d2 /= np.maximum(np.linalg.norm(d2, axis=1, keepdims=True), 1e-12)
    return np.stack([d1, d2, np.cross(d1, d2)], axis=1)


def _best_rotation(lines, mid, unit, weight, f: float, samples: np.ndarray, tol: float) -> tuple[np.ndarray, float]:
    """The hypothesis with the most inlier length at focal length ``f``: ``(3, 3)`` rows and its score."""
    dirs = _hypotheses(lines, f, samples)
    sines = _angle_sines(dirs, np.full(len(dirs), f), mid, unit).min(axis=1)  # (S, N)
    score = ((sines < tol) * weight).sum(axis=1)
    best = int(np.argmax(score))
    return dirs[best], float(score[best])


def frame_focal(seg: np.ndarray, image_size: tuple[int, int], focals: np.ndarray, angle_deg: float = 1.0,
                hypotheses: int = 400, seed: int = 0) -> LineFocal | None:
    """One frame's focal length from its segments ``(N, 4)``, or None when there are too few.

    Args:
        seg: ``(N, 4)`` segments from :func:`line_segments`.
        image_size: ``(H, W)``.
        focals: ``(F,)`` focal lengths (pixels) the RANSAC tries.
        angle_deg: a segment within this angle of a vanishing point is its inlier.
        hypotheses: RANSAC samples per focal length.
        seed: the sampler's seed (same segments, same answer).
    """
    if len(seg) < 12:
        return None
    h, w = image_size
    centre = np.array([(w - 1) / 2, (h - 1) / 2])
    lines, mid, unit, length = _segment_geometry(seg, centre)
    weight = np.sqrt(length)
    tol = np.sin(np.deg2rad(angle_deg))
    rng = np.random.default_rng(seed)
    pool = min(len(seg), 80)  # sample from the longest: more of them are the room's edges
    samples = np.stack([rng.choice(pool, 3, replace=False) for _ in range(hypotheses)])
    tried = [(_best_rotation(lines, mid, unit, weight, float(f), samples, tol), float(f)) for f in focals]
    (dirs, _), f0 = max(tried, key=lambda t: t[0][1])

    def residuals(p):
        R = Rotation.from_rotvec(p[1:]).as_matrix() @ dirs.T  # columns: the directions
        return weight * _angle_sines(R.T, np.exp(p[0]), mid, unit).min(axis=0)

    sol = least_squares(residuals, np.r_[np.log(f0), 0.0, 0.0, 0.0], loss="cauchy", f_scale=tol, method="trf",
                        x_scale=np.array([0.1, 0.01, 0.01, 0.01]), max_nfev=200)
    rotation = Rotation.from_rotvec(sol.x[1:]).as_matrix() @ dirs.T
    sines = _angle_sines(rotation.T, np.exp(sol.x[0]), mid, unit).min(axis=0)
    inlier = sines < tol
    if inlier.sum() < 8:
        return None
    J = sol.jac[inlier]
    sigma2 = float(np.sum(sol.fun[inlier] ** 2) / max(inlier.sum() - 4, 1))
    try:
        cov = np.linalg.inv(J.T @ J) * sigma2
        log_std = float(np.sqrt(max(cov[0, 0], 0.0)))
    except np.linalg.LinAlgError:
        log_std = float("inf")
    return LineFocal(float(np.exp(sol.x[0])), log_std, int(inlier.sum()), rotation)


def focal_from_lines(frames: np.ndarray, ranges, config: FocalConfig = FocalConfig()
                     ) -> tuple[FocalEstimate | None, str]:
    """The video's focal length from its straight edges (module docstring), or None and why not.

    Args:
        frames: ``(T, H, W, 3)`` uint8 RGB frames of the whole video.
        ranges: ``[(a, b)]`` frame ranges of its shots; ``config.line_frames`` frames of each are read.
    """
    frames = np.asarray(frames)
    if frames.ndim != 4 or frames.shape[-1] != 3 or frames.dtype != np.uint8:
        raise InputError(f"frames: expected (T, H, W, 3) uint8 RGB, got {frames.shape} {frames.dtype}")
    h, w = frames.shape[1:3]
    lo, hi = config.fov_range_deg
    focals = np.geomspace(focal_from_fov(w, hi), focal_from_fov(w, lo), 16)
    picked = sorted({int(i) for a, b in ranges if b > a
                     for i in np.linspace(a, b - 1, config.line_frames).round()})
    found = []
    for i in picked:
        gray = cv2.cvtColor(np.ascontiguousarray(frames[i]), cv2.COLOR_RGB2GRAY)
        one = frame_focal(line_segments(gray, config.min_line_length, config.max_line_segments), (h, w), focals,
                          config.line_angle_deg)
        if one is not None and one.log_std <= config.max_line_std and _in_range(one.focal_px, w, config):
            found.append(one.focal_px)
    if len(found) < config.min_line_frames:
        return None, f"{len(found)} of {len(picked)} frames pin it down"
    log_f = np.log(found)
    middle = float(np.median(log_f))
    agree = np.abs(log_f - middle) <= config.line_agreement
    if agree.mean() < 0.5:
        return None, f"the frames disagree ({int(agree.sum())} of {len(found)} within {100 * config.line_agreement:.0f} %)"
    spread = float(np.median(np.abs(log_f[agree] - middle)))
    return FocalEstimate(float(np.exp(middle)), "lines",
                         f"{len(found)} of {len(picked)} frames, median deviation {100 * spread:.1f} %"), ""
