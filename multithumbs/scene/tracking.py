"""Camera trajectory within a shot (DESIGN §1 stage 3, CPU path): KLT tracks and pycolmap geometry.

:func:`track_camera` works in three steps:

1. Tracks: Shi-Tomasi corners on the room (people's masks, dilated, are left out) followed frame to
   frame by pyramidal Lucas-Kanade optical flow with a forward-backward check, replenished at keyframes
   (every ``keyframe_interval`` frames or when too few survive). This replaces SIFT on every frame,
   which would take over a minute per 150 frames here; sequential matching comes for free.
2. Static camera: when the corners of the first frame have not moved by more than ``static_pixels``
   in any probed frame, every frame gets the identity camera (``source="static"``) and the work stops.
3. Otherwise sequential structure from motion with pycolmap: the first frame and the first frame with
   enough parallax initialise (essential matrix, refined), their common tracks are triangulated, then
   every frame is registered in order by pycolmap's absolute pose (LO-RANSAC + refinement) on its tracked
   map points while new tracks are triangulated as they gain parallax. Frames that fail to register are
   interpolated between their registered neighbours (held at the ends). A shot with motion but no
   parallax anywhere (a pan about the optical centre) gets rotations from homographies and no
   translation (``source="pycolmap:rotation_only"``).

The trajectory's frame is the shot's first camera (``R[0] = I``, ``t[0] = 0``) and its scale is
unknown (the initial baseline is 1); the shared space at a cut fixes it later. ``points`` is the sparse
room map in that frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from multithumbs.errors import InputError
from multithumbs.scene.two_view import dilate
from multithumbs.scene.two_view_pose import relative_pose, triangulate
from multithumbs.types import CameraTrajectory


@dataclass(frozen=True)
class TrackingConfig:
    """Settings of the intra-shot camera tracker.

    Attributes:
        max_corners: most corners tracked at once.
        corner_quality: Shi-Tomasi quality level (relative to the best corner).
        min_corner_distance: corners are at least this far apart (pixels).
        window: Lucas-Kanade window side (pixels).
        pyramid_levels: Lucas-Kanade pyramid levels above the full image.
        max_forward_backward_error: tracks whose forward-backward round trip misses by more are dropped (px).
        keyframe_interval: corners are replenished at least every this many frames.
        mask_dilation: people's masks grow by this many pixels before corners on them are dropped.
        static_pixels: a shot whose first-frame corners move at most this far (median, pixels) in every
            probed frame is static.
        static_probes: frames probed for the static test (evenly spread, last frame included).
        init_parallax: median track displacement (pixels) the initial pair needs.
        ransac_max_error: RANSAC threshold of the relative and absolute poses (pixels).
        min_points: fewest 2D-3D correspondences to register a frame.
        min_triangulation_angle_deg: a new track is triangulated once its views are this far apart.
        max_reprojection_error: triangulated points with a larger error are dropped (pixels).
    """

    max_corners: int = 600
    corner_quality: float = 0.01
    min_corner_distance: int = 8
    window: int = 21
    pyramid_levels: int = 3
    max_forward_backward_error: float = 0.5
    keyframe_interval: int = 10
    mask_dilation: int = 5
    static_pixels: float = 0.5
    static_probes: int = 8
    init_parallax: float = 25.0
    ransac_max_error: float = 1.0
    min_points: int = 12
    min_triangulation_angle_deg: float = 2.0
    max_reprojection_error: float = 2.0


@dataclass(frozen=True)
class Tracks:
    """KLT tracks of one shot: observation ``i`` is track ``track[i]`` at ``frame[i]``, pixel ``xy[i]``."""

    track: np.ndarray
    frame: np.ndarray
    xy: np.ndarray

    @property
    def num_tracks(self) -> int:
        return int(self.track.max()) + 1 if self.track.size else 0


def _room_masks(person_masks, count: int, image_size: tuple[int, int], dilation: int) -> list[np.ndarray | None]:
    if person_masks is None:
        return [None] * count
    masks = np.asarray(person_masks, bool)
    if masks.shape != (count, *image_size):
        raise InputError(f"person_masks: expected (T, H, W) = ({count}, {image_size[0]}, {image_size[1]}) "
                         f"bool masks, got {masks.shape}")
    out = []
    for m in masks:
        if m.any():
            m = dilate(m, dilation) if dilation > 0 else m
        out.append(~m)
    return out


def _lk(prev: np.ndarray, nxt: np.ndarray, pts: np.ndarray, config: TrackingConfig) -> tuple[np.ndarray, np.ndarray]:
    """Track ``pts (N, 2)`` from ``prev`` to ``nxt``; returns new positions and a keep mask."""
    params = dict(winSize=(config.window, config.window), maxLevel=config.pyramid_levels,
                  criteria=(cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 30, 0.01))
    p0 = pts.reshape(-1, 1, 2).astype(np.float32)
    p1, st1, _ = cv2.calcOpticalFlowPyrLK(prev, nxt, p0, None, **params)
    p0r, st2, _ = cv2.calcOpticalFlowPyrLK(nxt, prev, p1, None, **params)
    fb = np.linalg.norm(p0r.reshape(-1, 2) - p0.reshape(-1, 2), axis=1)
    keep = (st1.reshape(-1) == 1) & (st2.reshape(-1) == 1) & (fb <= config.max_forward_backward_error)
    return p1.reshape(-1, 2).astype(np.float64), keep


def _inside(xy: np.ndarray, room: np.ndarray | None, image_size: tuple[int, int]) -> np.ndarray:
    h, w = image_size
    ok = (xy[:, 0] >= 0) & (xy[:, 0] <= w - 1) & (xy[:, 1] >= 0) & (xy[:, 1] <= h - 1)
    if room is not None:
        u = np.clip(np.round(xy[:, 0]).astype(int), 0, w - 1)
        v = np.clip(np.round(xy[:, 1]).astype(int), 0, h - 1)
        ok &= room[v, u]
    return ok


def _corners(gray: np.ndarray, room: np.ndarray | None, existing: np.ndarray, count: int,
             config: TrackingConfig) -> np.ndarray:
    if count <= 0:
        return np.zeros((0, 2))
    mask = np.full(gray.shape, 255, np.uint8) if room is None else room.astype(np.uint8) * 255
    for x, y in existing:  # keep new corners away from tracked ones
        cv2.circle(mask, (int(round(x)), int(round(y))), config.min_corner_distance, 0, -1)
    found = cv2.goodFeaturesToTrack(gray, maxCorners=count, qualityLevel=config.corner_quality,
                                    minDistance=config.min_corner_distance, mask=mask, blockSize=7)
    return np.zeros((0, 2)) if found is None else found.reshape(-1, 2).astype(np.float64)


def klt_tracks(grays: list[np.ndarray], rooms: list[np.ndarray | None], config: TrackingConfig) -> Tracks:
    """Room tracks over the frames (module docstring, step 1)."""
    image_size = grays[0].shape
    pts = _corners(grays[0], rooms[0], np.zeros((0, 2)), config.max_corners, config)
    ids = np.arange(len(pts))
    next_id = len(pts)
    obs_t, obs_f, obs_xy = [ids], [np.zeros(len(pts), int)], [pts]
    last_key = 0
    for f in range(1, len(grays)):
        if len(pts):
            new, keep = _lk(grays[f - 1], grays[f], pts, config)
            keep &= _inside(new, rooms[f], image_size)
            pts, ids = new[keep], ids[keep]
        if f - last_key >= config.keyframe_interval or len(pts) < 0.6 * config.max_corners:
            extra = _corners(grays[f], rooms[f], pts, config.max_corners - len(pts), config)
            pts = np.concatenate([pts, extra])
            ids = np.concatenate([ids, np.arange(next_id, next_id + len(extra))])
            next_id += len(extra)
            last_key = f
        obs_t.append(ids)
        obs_f.append(np.full(len(ids), f))
        obs_xy.append(pts)
    return Tracks(np.concatenate(obs_t), np.concatenate(obs_f), np.concatenate(obs_xy).reshape(-1, 2))


def is_static(grays: list[np.ndarray], rooms: list[np.ndarray | None], config: TrackingConfig) -> bool:
    """True when the first frame's room corners stay put (median motion <= ``static_pixels``) in the probes."""
    pts = _corners(grays[0], rooms[0], np.zeros((0, 2)), config.max_corners, config)
    if len(pts) < 8:
        # Nothing to track (uniform or black frames): no evidence of motion either way; compare pixels.
        diffs = [float(np.abs(g.astype(np.int16) - grays[0]).mean()) for g in grays[1:]]
        return max(diffs, default=0.0) < 2.0
    probes = np.unique(np.linspace(1, len(grays) - 1, min(config.static_probes, len(grays) - 1)).round().astype(int))
    for f in probes:
        new, keep = _lk(grays[0], grays[f], pts, config)
        if keep.sum() < 0.3 * len(pts):
            return False
        if np.median(np.linalg.norm(new[keep] - pts[keep], axis=1)) > config.static_pixels:
            return False
    return True


def _colmap_camera(K: np.ndarray, image_size: tuple[int, int]):
    from multithumbs.scene.two_view_pose import _colmap_camera as make

    return make(K, image_size)


def track_camera(frames: np.ndarray, K: np.ndarray, person_masks=None, shot_index: int = 0, start_frame: int = 0,
                 config: TrackingConfig = TrackingConfig()) -> CameraTrajectory:
    """Cameras of one shot in the shot's own frame and scale (module docstring).

    Args:
        frames: ``(T, H, W, 3)`` uint8 RGB frames of the shot.
        K: ``(3, 3)`` intrinsics.
        person_masks: ``(T, H, W)`` bool union of the people's masks per frame, or None.
        shot_index: which shot (recorded in the result).
        start_frame: video frame of the shot's first frame (recorded).
    """
    frames = np.asarray(frames)
    if frames.ndim != 4 or frames.shape[-1] != 3 or frames.dtype != np.uint8:
        raise InputError(f"frames: expected (T, H, W, 3) uint8 RGB, got {frames.shape} {frames.dtype}")
    count = len(frames)
    if count == 0:
        raise InputError(f"shot {shot_index}: no frames")
    K = np.asarray(K, np.float64)
    if K.shape != (3, 3):
        raise InputError(f"K: expected (3, 3) intrinsics, got {K.shape}")
    image_size = frames.shape[1:3]
    identity = dict(shot_index=shot_index, start_frame=start_frame, K=K, R=np.tile(np.eye(3), (count, 1, 1)),
                    t=np.zeros((count, 3)))
    if count == 1:
        return CameraTrajectory(**identity, source="static")
    grays = [cv2.cvtColor(np.ascontiguousarray(f), cv2.COLOR_RGB2GRAY) for f in frames]
    rooms = _room_masks(person_masks, count, image_size, config.mask_dilation)
    if is_static(grays, rooms, config):
        return CameraTrajectory(**identity, source="static")
    tracks = klt_tracks(grays, rooms, config)
    result = _sequential_sfm(tracks, count, K, image_size, config)
    if result is None:
        R = _rotations_from_homographies(tracks, count, K, config)
        return CameraTrajectory(shot_index=shot_index, start_frame=start_frame, K=K, R=R, t=np.zeros((count, 3)),
                                source="pycolmap:rotation_only")
    R, t, points = result
    return CameraTrajectory(shot_index=shot_index, start_frame=start_frame, K=K, R=R, t=t,
                            points=points if len(points) else None, source="pycolmap")


def _track_table(tracks: Tracks, count: int) -> tuple[np.ndarray, np.ndarray]:
    """Dense ``(T, N, 2)`` pixel table and ``(T, N)`` presence of every track in every frame."""
    n = tracks.num_tracks
    xy = np.full((count, n, 2), np.nan)
    seen = np.zeros((count, n), bool)
    xy[tracks.frame, tracks.track] = tracks.xy
    seen[tracks.frame, tracks.track] = True
    return xy, seen


def _sequential_sfm(tracks: Tracks, count: int, K: np.ndarray, image_size: tuple[int, int],
                    config: TrackingConfig) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Sequential registration (module docstring, step 3); None when no pair has parallax."""
    import pycolmap

    xy, seen = _track_table(tracks, count)
    # Initial pair: frame 0 and the first frame whose common tracks moved enough.
    init = None
    best = (0.0, None)
    for f in range(1, count):
        common = seen[0] & seen[f]
        if common.sum() < config.min_points:
            break
        parallax = float(np.median(np.linalg.norm(xy[f, common] - xy[0, common], axis=1)))
        if parallax > best[0]:
            best = (parallax, f)
        if parallax >= config.init_parallax:
            init = f
            break
    if init is None:
        init = best[1]
    if init is None:
        return None
    common = seen[0] & seen[init]
    pose = relative_pose(xy[0, common], xy[init, common], K, K, image_size, config.ransac_max_error)
    if pose is None:
        return None
    idx = np.nonzero(common)[0][pose.inliers]
    pts, err, angle = triangulate(xy[0, idx], xy[init, idx], K, K, pose.R, pose.t)
    good = (err <= config.max_reprojection_error) & (angle >= 0.5)
    if good.sum() < config.min_points or np.median(angle[good]) < config.min_triangulation_angle_deg / 2:
        return None
    n = xy.shape[1]
    points = np.full((n, 3), np.nan)
    points[idx[good]] = pts[good]
    R = np.full((count, 3, 3), np.nan)
    t = np.full((count, 3), np.nan)
    R[0], t[0] = np.eye(3), np.zeros(3)
    R[init], t[init] = pose.R, pose.t
    camera = _colmap_camera(K, image_size)
    options = pycolmap.AbsolutePoseEstimationOptions()
    options.ransac.max_error = config.ransac_max_error
    options.ransac.random_seed = 0  # reproducible trajectories from the same frames
    first_seen = np.argmax(seen, axis=0)
    for f in range(1, count):
        if f != init:
            known = seen[f] & np.isfinite(points[:, 0])
            if known.sum() >= config.min_points:
                result = pycolmap.estimate_and_refine_absolute_pose(
                    np.ascontiguousarray(xy[f, known] + 0.5), np.ascontiguousarray(points[known]), camera, options)
                if result is not None and result["num_inliers"] >= config.min_points:
                    pose_f = result["cam_from_world"]
                    R[f], t[f] = pose_f.rotation.matrix(), pose_f.translation
        if not np.isfinite(R[f, 0, 0]):
            continue
        # Triangulate tracks seen here and at their first registered sighting, once the views are apart.
        fresh = seen[f] & ~np.isfinite(points[:, 0])
        for g in np.unique(first_seen[fresh]):
            if not np.isfinite(R[g, 0, 0]) or g == f:
                continue
            sel = np.nonzero(fresh & (first_seen == g) & seen[g])[0]
            if len(sel) == 0:
                continue
            R_rel = R[f] @ R[g].T
            t_rel = t[f] - R_rel @ t[g]
            p_g, err, angle = triangulate(xy[g, sel], xy[f, sel], K, K, R_rel, t_rel)
            ok = (err <= config.max_reprojection_error) & (angle >= config.min_triangulation_angle_deg)
            points[sel[ok]] = (p_g[ok] - t[g]) @ R[g]
    registered = np.isfinite(R[:, 0, 0])
    if registered.sum() < 2:
        return None
    R, t = _interpolate_missing(R, t, registered)
    return R, t, points[np.isfinite(points[:, 0])]


def _interpolate_missing(R: np.ndarray, t: np.ndarray, registered: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Fill unregistered frames: rotations by slerp, camera centres linearly, held at the ends."""
    frames = np.nonzero(registered)[0]
    if registered.all():
        return R, t
    centres = -np.einsum("fji,fj->fi", R[frames], t[frames])
    slerp = Slerp(frames, Rotation.from_matrix(R[frames]))
    every = np.arange(len(R))
    clamped = np.clip(every, frames[0], frames[-1])
    R_all = slerp(clamped).as_matrix()
    C_all = np.stack([np.interp(clamped, frames, centres[:, k]) for k in range(3)], axis=1)
    t_all = -np.einsum("fij,fj->fi", R_all, C_all)
    R_all[registered], t_all[registered] = R[registered], t[registered]
    return R_all, t_all


def _rotations_from_homographies(tracks: Tracks, count: int, K: np.ndarray, config: TrackingConfig) -> np.ndarray:
    """Rotation-only cameras: each frame's rotation from the homography of its tracks to the previous frame."""
    xy, seen = _track_table(tracks, count)
    R = np.tile(np.eye(3), (count, 1, 1))
    K_inv = np.linalg.inv(K)
    for f in range(1, count):
        common = seen[f - 1] & seen[f]
        R_step = np.eye(3)
        if common.sum() >= 8:
            H, _ = cv2.findHomography(xy[f - 1, common], xy[f, common], cv2.RANSAC, 2.0 * config.ransac_max_error)
            if H is not None:
                U, _, Vt = np.linalg.svd(K_inv @ H @ K)
                R_step = U @ Vt
                if np.linalg.det(R_step) < 0:
                    R_step = U @ np.diag([1.0, 1.0, -1.0]) @ Vt
        R[f] = R_step @ R[f - 1]
    return R
