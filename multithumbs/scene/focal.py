"""The focal length of a camera nobody calibrated, from the pixels (issue #17).

Real footage comes without intrinsics. :func:`estimate_focal` tries, in this order, and records which
source gave the focal length (square pixels and the principal point at the image centre throughout):

1. ``lines`` (:func:`multithumbs.scene.focal_lines.focal_from_lines`): straight edges along three orthogonal
   directions (floor planks, wall corners, furniture, door frames) meet at vanishing points whose
   orthogonality fixes the focal length; a few frames per shot, each refined on its segments, the median of
   the frames that pin it down. A level camera looking square at a wall does not. First because it is the
   more reliable where both answer: rendered at a 40 degree field of view, a sideways dolly's profile
   accepted 381 px for 879 px, the lines 883 px (docs/RESULTS.md, session 20).
2. ``moving_camera`` (:func:`focal_from_motion`): a shot whose camera moves. Room corners tracked by KLT
   through the shot (:func:`multithumbs.scene.tracking.klt_tracks`, people masked out), a handful of
   keyframes, then a bundle adjustment with the focal length free (scipy, Huber loss, started from several
   fields of view). The estimate is kept only when the adjustment pins it down: the starts that fit
   about as well as the best must agree within 3 %. A sideways dolly (the suite's moving cameras) does not:
   to first order its flow is the same for every focal length (the translation's parallax absorbs the
   rotation's), and the starts stay where they began. A camera that turns about its centre (a pan: homographies
   explain the tracks) gives ``rotating_camera``: the focal length that makes ``K^-1 H K`` a rotation. A
   static camera gives nothing.
3. ``learned``: a learned scene model's intrinsics (VGGT or Depth-Anything-3 through
   :mod:`multithumbs.scene.learned`), when the caller gives one (:func:`focal_from_learned`).
4. ``heights`` (:func:`multithumbs.scene.focal_heights.focal_from_heights`): standing people as vertical poles of one height. Every
   person-frame gives a foot point (mid-ankle) and a top point (mid-shoulder); a camera of unknown focal
   length, pitch, roll and height above a common floor is fitted so that each foot point, put on the floor,
   projects its top point at the pole's height. Needs people at different depths; otherwise nothing.
5. ``default``: the 60 degree guess (:func:`multithumbs.scene.two_view.default_intrinsics`), its detail
   saying why nothing else applied.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Sequence

import cv2
import numpy as np
from scipy.optimize import least_squares
from scipy.sparse import lil_matrix
from scipy.spatial.transform import Rotation

from multithumbs.errors import InputError
from multithumbs.geometry import intrinsics

SOURCES = ("given", "lines", "moving_camera", "rotating_camera", "learned", "heights", "default")
SOURCE_WORDS = {"given": "given", "moving_camera": "moving camera", "rotating_camera": "rotating camera",
                "lines": "vanishing points",
                "learned": "learned model", "heights": "people's heights", "default": "default 60° guess"}


@dataclass(frozen=True)
class FocalEstimate:
    """A focal length in pixels (square pixels, centred principal point) and where it came from.

    Attributes:
        focal_px: the focal length (pixels).
        source: one of :data:`SOURCES`.
        detail: which shot, how many observations, the relative standard deviation, or why a source failed.
    """

    focal_px: float
    source: str
    detail: str = ""

    def K(self, width: int, height: int) -> np.ndarray:
        """``(3, 3)`` intrinsics of a ``width`` x ``height`` video."""
        return intrinsics(self.focal_px, self.focal_px, (width - 1) / 2, (height - 1) / 2)

    def line(self) -> str:
        """One short line for a user, e.g. ``focal length 612 px (moving camera, shot 2)``."""
        words = SOURCE_WORDS.get(self.source, self.source)
        return f"focal length {self.focal_px:.0f} px ({words}{', ' + self.detail if self.detail else ''})"

    def to_json(self) -> dict:
        return {"focal_px": float(self.focal_px), "source": self.source, "detail": self.detail}


@dataclass(frozen=True)
class FocalConfig:
    """Settings of the focal length estimation.

    Attributes:
        keyframes: keyframes of a moving shot in the bundle adjustment.
        min_tracks: fewest room tracks common to the first and last keyframe.
        min_parallax: median track motion (pixels) between the first and last keyframe for a moving camera.
        init_fovs_deg: horizontal fields of view the heights fit starts from.
        profile_steps: focal lengths (geometric, over ``fov_range_deg``) the moving camera's profile tries.
        min_profile_rise: the profile's RMS must rise by this fraction one step either side of its minimum.
        rotation_ratio: homography inliers at least this fraction of the fundamental matrix's: a rotation.
        min_rotation_deg: a rotating camera must turn at least this far for its focal length to count.
        min_heights: fewest person-frames for the heights estimate.
        min_depth_spread: foot rows must spread over this fraction of the image height (people at depths).
        fov_range_deg: estimates outside this horizontal field of view are refused.
        line_frames: frames of each shot whose straight edges are read.
        min_line_length: shortest line segment used (pixels).
        max_line_segments: at most this many segments per frame, longest first.
        line_angle_deg: a segment within this angle of a vanishing point belongs to it.
        max_line_std: a frame counts when the standard deviation of its ``log f`` is at most this.
        min_line_frames: fewest frames that must count.
        line_agreement: at least half the frames that count within this of their median (in ``log f``).
    """

    keyframes: int = 8
    min_tracks: int = 40
    min_parallax: float = 8.0
    init_fovs_deg: tuple[float, ...] = (35.0, 60.0, 90.0)
    profile_steps: int = 24
    min_profile_rise: float = 0.15
    rotation_ratio: float = 0.9
    min_rotation_deg: float = 3.0
    min_heights: int = 20
    min_depth_spread: float = 0.08
    fov_range_deg: tuple[float, float] = (15.0, 120.0)
    line_frames: int = 6
    min_line_length: float = 20.0
    max_line_segments: int = 300
    line_angle_deg: float = 1.0
    max_line_std: float = 0.03
    min_line_frames: int = 3
    line_agreement: float = 0.05


def given_focal(K: np.ndarray) -> FocalEstimate:
    """The estimate of intrinsics a user gave: ``sqrt(fx fy)``."""
    K = np.asarray(K, np.float64)
    return FocalEstimate(float(np.sqrt(K[0, 0] * K[1, 1])), "given")


def focal_from_fov(width: int, horizontal_fov_deg: float) -> float:
    """Focal length (pixels) of a ``width``-pixel image with that horizontal field of view."""
    return 0.5 * width / np.tan(np.deg2rad(horizontal_fov_deg) / 2)


def _in_range(f: float, width: int, config: FocalConfig) -> bool:
    lo, hi = config.fov_range_deg
    return bool(np.isfinite(f) and focal_from_fov(width, hi) <= f <= focal_from_fov(width, lo))


# ----------------------------------------------------------------------------------------------------
# 1. A moving camera: bundle adjustment with the focal length free


def _project(params: np.ndarray, n_views: int, n_points: int, view: np.ndarray, point: np.ndarray,
             centre: np.ndarray) -> np.ndarray:
    f = np.exp(params[0])
    poses = params[1:1 + 6 * (n_views - 1)].reshape(-1, 6)
    X = params[1 + 6 * (n_views - 1):].reshape(n_points, 3)
    R = np.concatenate([np.eye(3)[None], Rotation.from_rotvec(poses[:, :3]).as_matrix()])
    t = np.concatenate([np.zeros((1, 3)), poses[:, 3:]])
    cam = np.einsum("nij,nj->ni", R[view], X[point]) + t[view]
    z = np.where(np.abs(cam[:, 2]) < 1e-9, 1e-9, cam[:, 2])
    return f * cam[:, :2] / z[:, None] + centre


def _sparsity(n_views: int, n_points: int, view: np.ndarray, point: np.ndarray) -> lil_matrix:
    m = len(view)
    J = lil_matrix((2 * m + 1, 1 + 6 * (n_views - 1) + 3 * n_points), dtype=int)
    rows = np.arange(m)
    for r in (2 * rows, 2 * rows + 1):
        J[r, 0] = 1
        for k in range(6):
            on = view > 0
            J[r[on], 1 + 6 * (view[on] - 1) + k] = 1
        for k in range(3):
            J[r, 1 + 6 * (n_views - 1) + 3 * point + k] = 1
    J[2 * m, 1 + 6 * (n_views - 2) + 3:1 + 6 * (n_views - 1)] = 1  # the scale gauge: |t_last| = 1
    return J


def _initial_params(xy: np.ndarray, f0: float, centre: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """Poses and points for focal ``f0`` from tracks ``xy (V, N, 2)`` seen in every keyframe; None on failure."""
    V = len(xy)
    K = intrinsics(f0, f0, *centre)
    E, inl = cv2.findEssentialMat(xy[0], xy[-1], K, cv2.RANSAC, 0.999, 1.0)
    if E is None or E.shape != (3, 3):
        return None
    _, R, t, inl = cv2.recoverPose(E, xy[0], xy[-1], K, mask=inl)
    keep = inl.ravel() > 0
    if keep.sum() < 12:
        return None
    P0 = K @ np.eye(3, 4)
    P1 = K @ np.c_[R, t]
    Xh = cv2.triangulatePoints(P0, P1, xy[0].T, xy[-1].T)
    X = (Xh[:3] / Xh[3]).T
    poses = []
    for v in range(1, V):
        if v == V - 1:
            poses.append(np.r_[Rotation.from_matrix(R).as_rotvec(), t.ravel()])
            continue
        ok, rvec, tvec = cv2.solvePnP(X[keep], xy[v, keep], K, None, flags=cv2.SOLVEPNP_ITERATIVE)
        if not ok:
            return None
        poses.append(np.r_[rvec.ravel(), tvec.ravel()])
    return np.r_[np.log(f0), np.concatenate(poses), X.ravel()], keep


def bundle_profile(xy: np.ndarray, image_size: tuple[int, int], focals: Sequence[float]) -> np.ndarray:
    """Reprojection RMS (pixels) of a bundle adjustment of keyframe tracks with the focal length held at each
    of ``focals``: the profile whose minimum is the estimate and whose rise around it says how well the
    motion determines it.

    Args:
        xy: ``(V, N, 2)`` pixels of ``N`` points seen in all ``V >= 3`` keyframes.
        image_size: ``(H, W)``.
        focals: ``(F,)`` focal lengths (pixels).
    Returns:
        ``(F,)`` RMS per focal length (inf where the start failed).
    """
    cv2.setRNGSeed(0)  # RANSAC: the same tracks give the same profile (artifact keys mean the same bytes)
    xy = np.asarray(xy, np.float64)
    if xy.ndim != 3 or xy.shape[0] < 3 or xy.shape[2] != 2 or xy.shape[1] < 12:
        raise InputError(f"bundle_profile: expected (V>=3, N>=12, 2) keyframe tracks, got {xy.shape}")
    h, w = image_size
    centre = np.array([(w - 1) / 2, (h - 1) / 2])
    V, N = xy.shape[:2]
    out = np.full(len(focals), np.inf)
    for i, f0 in enumerate(focals):
        start = _initial_params(xy, float(f0), centre)
        if start is None:
            continue
        x0, keep = start
        pts = np.nonzero(keep)[0]
        n = len(pts)
        x0 = np.r_[x0[1:1 + 6 * (V - 1)], x0[1 + 6 * (V - 1):].reshape(N, 3)[pts].ravel()]
        view, point = np.repeat(np.arange(V), n), np.tile(np.arange(n), V)
        obs = xy[:, pts].reshape(-1, 2)
        last = slice(6 * (V - 2) + 3, 6 * (V - 1))
        log_f = np.log(f0)

        def residuals(p):
            r = (_project(np.r_[log_f, p], V, n, view, point, centre) - obs).ravel()
            return np.r_[r, 10.0 * (np.linalg.norm(p[last]) - 1.0)]

        sparsity = _sparsity(V, n, view, point)[:, 1:]
        sol = least_squares(residuals, x0, jac_sparsity=sparsity, loss="huber", f_scale=1.0, x_scale="jac",
                            method="trf", max_nfev=50)
        r = sol.fun[:-1].reshape(-1, 2)
        good = np.linalg.norm(r, axis=1) < 3.0  # outlier tracks (people, occlusions) out of the score
        if good.mean() > 0.5:
            out[i] = float(np.sqrt(np.mean(r[good] ** 2)))
    return out


def profile_minimum(focals: np.ndarray, rms: np.ndarray, min_rise: float) -> tuple[float | None, float]:
    """The profile's minimum (parabola in ``log f`` through the lowest point and its neighbours) and the
    relative rise of the RMS at the neighbours; None when the minimum is at an end or the rise is below
    ``min_rise``."""
    i = int(np.argmin(rms))
    if i == 0 or i == len(rms) - 1 or not np.isfinite(rms[i]):
        return None, 0.0
    rise = float(min(rms[i - 1], rms[i + 1]) / rms[i] - 1.0)
    x, y = np.log(focals[i - 1:i + 2]), rms[i - 1:i + 2] ** 2
    a, b, _ = np.polyfit(x, y, 2)
    log_f = -b / (2 * a) if a > 0 else x[1]
    return (float(np.exp(np.clip(log_f, x[0], x[2]))) if rise >= min_rise else None), rise


def focal_from_rotation(xy_a: np.ndarray, xy_b: np.ndarray, image_size: tuple[int, int]) -> tuple[float, float]:
    """Focal length of a camera turning about its centre from matches ``(N, 2)``: the ``f`` that makes
    ``K^-1 H K`` a rotation. Returns ``(focal_px, rotation_deg)``."""
    from scipy.optimize import minimize_scalar

    h, w = image_size
    H, _ = cv2.findHomography(xy_a, xy_b, cv2.RANSAC, 1.0)
    if H is None:
        return float("nan"), 0.0
    cx, cy = (w - 1) / 2, (h - 1) / 2

    def rotation(log_f):
        K = intrinsics(np.exp(log_f), np.exp(log_f), cx, cy)
        M = np.linalg.inv(K) @ H @ K
        return M / np.cbrt(np.linalg.det(M))

    cost = lambda log_f: float(np.linalg.norm(rotation(log_f) @ rotation(log_f).T - np.eye(3)))
    sol = minimize_scalar(cost, bounds=(np.log(focal_from_fov(w, 170.0)), np.log(focal_from_fov(w, 3.0))),
                          method="bounded")
    angle = np.rad2deg(Rotation.from_matrix(rotation(sol.x)).magnitude()) if cost(sol.x) < 0.05 else 0.0
    return float(np.exp(sol.x)), float(angle)


def focal_from_motion(frames: np.ndarray, masks: np.ndarray | None = None, config: FocalConfig = FocalConfig()
                      ) -> tuple[FocalEstimate | None, str]:
    """The focal length from one shot whose camera moves (module docstring, 1), or None and why not.

    Args:
        frames: ``(T, H, W, 3)`` uint8 RGB frames of one shot.
        masks: ``(T, H, W)`` bool people masks (left out of the tracks), or None.
    """
    frames = np.asarray(frames)
    if frames.ndim != 4 or frames.shape[-1] != 3 or frames.dtype != np.uint8:
        raise InputError(f"frames: expected (T, H, W, 3) uint8 RGB, got {frames.shape} {frames.dtype}")
    image_size = frames.shape[1:3]
    xy, why = _keyframe_tracks(frames, masks, config)
    if xy is None:
        return None, why
    cv2.setRNGSeed(0)
    F, f_inl = cv2.findFundamentalMat(xy[0], xy[-1], cv2.FM_RANSAC, 1.0, 0.999)
    H, h_inl = cv2.findHomography(xy[0], xy[-1], cv2.RANSAC, 1.0)
    if H is not None and (F is None or h_inl.sum() >= config.rotation_ratio * f_inl.sum()):
        f, angle = focal_from_rotation(xy[0], xy[-1], image_size)
        if angle < config.min_rotation_deg or not _in_range(f, image_size[1], config):
            return None, f"camera turns {angle:.1f}°, too little"
        return FocalEstimate(f, "rotating_camera", f"turning {angle:.0f}°"), ""
    lo, hi = config.fov_range_deg
    focals = np.geomspace(focal_from_fov(image_size[1], hi), focal_from_fov(image_size[1], lo), config.profile_steps)
    f, rise = profile_minimum(focals, bundle_profile(xy, image_size, focals), config.min_profile_rise)
    if f is None:
        return None, f"the motion does not pin the focal length down (profile rise {100 * rise:.1f} %)"
    return FocalEstimate(f, "moving_camera", f"{xy.shape[0]} keyframes, {xy.shape[1]} tracks"), ""


def _keyframe_tracks(frames: np.ndarray, masks: np.ndarray | None, config: FocalConfig, tracking=None
                     ) -> tuple[np.ndarray | None, str]:
    """``(V, N, 2)`` room tracks seen in every keyframe of a shot, or None and why not."""
    from multithumbs.scene.tracking import TrackingConfig, _room_masks, _track_table, is_static, klt_tracks

    tracking = tracking or TrackingConfig(max_corners=1000, min_corner_distance=6)
    count = len(frames)
    if count < 2:
        return None, "a one-frame shot"
    grays = [cv2.cvtColor(np.ascontiguousarray(f), cv2.COLOR_RGB2GRAY) for f in frames]
    rooms = _room_masks(masks, count, frames.shape[1:3], tracking.mask_dilation)
    if is_static(grays, rooms, tracking):
        return None, "static camera"
    if count < config.keyframes:
        return None, f"shot too short ({count} frames)"
    xy, seen = _track_table(klt_tracks(grays, rooms, tracking), count)
    common = np.cumprod(seen, axis=0).astype(bool).sum(axis=1) if seen.size else np.zeros(count, int)
    enough = np.nonzero(common >= config.min_tracks)[0]  # frames still holding enough tracks from frame 0
    if not len(enough):
        return None, f"fewer than {config.min_tracks} room tracks"
    last = int(enough.max())
    if last < config.keyframes - 1:
        return None, "tracks too short"
    keys = np.unique(np.linspace(0, last, config.keyframes).round().astype(int))
    alive = seen[keys].all(axis=0)
    out = xy[keys][:, alive]
    if np.median(np.linalg.norm(out[-1] - out[0], axis=1)) < config.min_parallax:
        return None, "camera barely moves"
    return out, ""


# ----------------------------------------------------------------------------------------------------
# 2. Learned models; the chain


def focal_from_learned(space) -> FocalEstimate:
    """The focal length of a learned model's :class:`~multithumbs.types.SharedSpace` (VGGT or
    Depth-Anything-3, :mod:`multithumbs.scene.learned`): the geometric mean of ``fx, fy`` over its frames."""
    K = np.asarray(space.K, np.float64).reshape(-1, 3, 3)
    f = float(np.exp(np.mean(np.log(K[:, 0, 0] * K[:, 1, 1]) / 2)))
    if not np.isfinite(f) or f <= 0:
        raise InputError(f"{space.source}: the model's intrinsics have no positive focal length")
    return FocalEstimate(f, "learned", space.source)


def estimate_focal(frames: np.ndarray, ranges: Sequence[tuple[int, int]], masks: np.ndarray | None = None,
                   tracks: Sequence | None = None, learned: Callable[[np.ndarray, np.ndarray], object] | None = None,
                   config: FocalConfig = FocalConfig(), from_frames: tuple | None = None) -> FocalEstimate:
    """The video's focal length from the best source that gives one (module docstring).

    Args:
        frames: ``(T, H, W, 3)`` uint8 RGB frames of the whole video.
        ranges: ``[(a, b)]`` frame ranges of its shots.
        masks: ``(T, H, W)`` bool people masks, or None.
        tracks: per shot :class:`~multithumbs.types.PersonTracks` for the heights estimate, or None (skipped).
        learned: ``(frame_a, frame_b) -> SharedSpace`` of a loaded learned model (e.g.
            ``functools.partial(vggt_shared_space, model, cut_frame=0)``), or None.
        from_frames: :func:`frames_estimate`'s answer when already computed (perception runs between the two).
    """
    frames = np.asarray(frames)
    if frames.ndim != 4 or frames.shape[-1] != 3 or frames.dtype != np.uint8:
        raise InputError(f"frames: expected (T, H, W, 3) uint8 RGB, got {frames.shape} {frames.dtype}")
    h, w = frames.shape[1:3]
    estimate, why = from_frames if from_frames is not None else frames_estimate(frames, ranges, masks, config)
    if estimate is not None:
        return estimate
    reasons = [why]
    if learned is not None:
        a, b = ranges[0]
        return focal_from_learned(learned(frames[a], frames[min(a + max(1, (b - a) // 2), b - 1)]))
    if tracks is not None:
        from multithumbs.scene.focal_heights import focal_from_heights  # it builds on this module's types

        estimate, why = focal_from_heights(tracks, (h, w), config)
        if estimate is not None:
            return estimate
        reasons.append(f"heights: {why}")
    return FocalEstimate(float(focal_from_fov(w, 60.0)), "default", "; ".join(reasons))


def frames_estimate(frames: np.ndarray, ranges: Sequence[tuple[int, int]], masks: np.ndarray | None = None,
                    config: FocalConfig = FocalConfig()) -> tuple[FocalEstimate | None, str]:
    """The focal length from the frames alone (straight edges, else a moving camera; module docstring 1-2),
    or None and why not (``lines: ...; moving camera: ...``). Perception needs none of it."""
    from multithumbs.scene.focal_lines import focal_from_lines  # it builds on this module's types

    estimate, why_lines = focal_from_lines(frames, ranges, config)
    if estimate is not None:
        return estimate, ""
    estimate, why_motion = motion_estimate(frames, ranges, masks, config)
    if estimate is not None:
        return estimate, ""
    return None, f"lines: {why_lines}; moving camera: {why_motion}"


def motion_estimate(frames: np.ndarray, ranges: Sequence[tuple[int, int]], masks: np.ndarray | None = None,
                    config: FocalConfig = FocalConfig()) -> tuple[FocalEstimate | None, str]:
    """The first shot whose moving camera gives a focal length (detail: ``shot k, ...``), or None and why not."""
    reasons = []
    for k, (a, b) in enumerate(ranges):
        estimate, why = focal_from_motion(frames[a:b], None if masks is None else masks[a:b], config)
        if estimate is not None:
            return FocalEstimate(estimate.focal_px, estimate.source, f"shot {k}, {estimate.detail}"), ""
        reasons.append(why)
    counts = {r: reasons.count(r) for r in reasons}
    return None, ", ".join(f"{r} ({n} shot{'s' if n > 1 else ''})" for r, n in counts.items())
