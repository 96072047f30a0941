"""SIMULATED scene geometry for synthetic benchmarks — stand-ins for VGGT and DROID-SLAM.

These are simulations, labelled ``source="simulated"`` in every contract they produce:

* :func:`simulate_shared_space` plays VGGT at a cut: dense point maps and cameras of the two boundary
  frames from the renderer's exact depth, with depth noise, camera error, an unknown scale and an
  arbitrary world frame, so the alignment has real work to do.
* :func:`simulate_camera_trajectory` plays DROID-SLAM within a shot: the true cameras expressed in the
  shot's first camera frame, with drift and an unknown scale, plus a sparse map of scene points.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from multithumbs.geometry import (Similarity, axis_angle_to_matrix, camera_centre, project, transform_cameras,
                                  unproject)
from multithumbs.synth.scene import SyntheticVideo
from multithumbs.types import CameraTrajectory, SharedSpace


@dataclass(frozen=True)
class SharedSpaceNoise:
    """Errors of the simulated shared space.

    Attributes:
        depth_sigma: relative per-point depth noise (std).
        rotation_deg: camera rotation error (std of the angle, degrees).
        translation_sigma: camera centre error relative to the scene depth (std).
        scale_range: the space's unknown scale is drawn log-uniformly in this range.
        stride: keep every ``stride``-th pixel in each direction of the dense point maps.
        min_shared_background: below this share of the room seen by both boundary frames
            (:func:`shared_background`) there is nothing to register the frames by, and the space is a
            fallback without points or cameras, as the pixel backends give (a reverse shot that sees the
            other side of the room).
    """

    depth_sigma: float = 0.01
    rotation_deg: float = 0.5
    translation_sigma: float = 0.01
    scale_range: tuple[float, float] = (0.3, 3.0)
    stride: int = 2
    min_shared_background: float = 0.05


def shared_background(video: SyntheticVideo, cut_index: int, stride: int = 4, tolerance: float = 0.03) -> float:
    """The share of the room that both boundary frames of a cut see: for each frame, the fraction of its room
    pixels (every ``stride``-th) whose true point the other frame also sees (in its image, at its depth
    within ``tolerance``, not on a person); the smaller of the two."""
    world = video.truth.world
    cut = int(world.cut_frames[cut_index])
    frames = (cut - 1, cut)
    h, w = world.image_size
    vs, us = np.mgrid[0:h:stride, 0:w:stride]
    shares = []
    for k, f in enumerate(frames):
        g = frames[1 - k]
        depth = video.boundary_depth[cut_index, k][vs, us].ravel().astype(float)
        room = np.isfinite(depth) & (video.instance[f][vs, us].ravel() < 0)
        if not room.any():
            return 0.0
        pix = np.stack([us.ravel(), vs.ravel()], axis=1)[room].astype(float)
        world_pts = (unproject(pix, depth[room], world.K[f]) - world.t[f]) @ world.R[f]
        cam = world_pts @ world.R[g].T + world.t[g]
        z = cam[:, 2]
        uv = project(cam, world.K[g])
        ui, vi = np.round(uv[:, 0]).astype(int), np.round(uv[:, 1]).astype(int)
        seen = (z > 1e-6) & (ui >= 0) & (ui < w) & (vi >= 0) & (vi < h)
        other = video.boundary_depth[cut_index, 1 - k]
        seen[seen] &= (np.abs(other[vi[seen], ui[seen]] - z[seen]) < tolerance * z[seen]) & \
            (video.instance[g][vi[seen], ui[seen]] < 0)
        shares.append(float(seen.mean()))
    return min(shares)


def _random_similarity(rng: np.random.Generator, scale_range: tuple[float, float]) -> Similarity:
    scale = np.exp(rng.uniform(*np.log(scale_range)))
    return Similarity.from_numpy(scale, axis_angle_to_matrix(rng.normal(size=3)), rng.normal(0, 2.0, size=3))


def simulate_shared_space(video: SyntheticVideo, cut_index: int, noise: SharedSpaceNoise = SharedSpaceNoise(),
                          seed: int = 0) -> SharedSpace:
    """SIMULATED VGGT output at cut ``cut_index``: point maps of frames ``(t_b - 1, t_b)`` in an arbitrary frame."""
    world = video.truth.world
    cut = int(world.cut_frames[cut_index])
    rng = np.random.default_rng([video.scene.config.seed, seed, cut, 11])
    h, w = world.image_size
    frames = (cut - 1, cut)
    share = shared_background(video, cut_index)
    if share < noise.min_shared_background:
        return SharedSpace(cut_frame=cut, K=world.K[list(frames)], R=np.stack([np.eye(3)] * 2), t=np.zeros((2, 3)),
                           points=np.zeros((0, 3)), pixels=np.zeros((2, 0, 2)), observed=np.zeros((2, 0), bool),
                           confidence=np.zeros(0), image_size=(h, w), source="simulated",
                           fallback=f"no shared background ({100 * share:.1f}% of the room in both frames)")
    vs, us = np.mgrid[0:h:noise.stride, 0:w:noise.stride]
    pix = np.stack([us.ravel(), vs.ravel()], axis=1).astype(float)
    points, pixels, observed, conf = [], [], [], []
    R_noisy, t_noisy = [], []
    for k, f in enumerate(frames):
        depth = video.boundary_depth[cut_index, k][vs, us].ravel().astype(float)
        keep = np.isfinite(depth)
        d = depth[keep] * (1 + noise.depth_sigma * rng.standard_normal(keep.sum()))
        cam_pts = unproject(pix[keep], d, world.K[f])
        # Camera error: perturb the camera; points stay attached to their pixels (as a network predicts them).
        dR = axis_angle_to_matrix(rng.normal(size=3) * np.deg2rad(noise.rotation_deg) / np.sqrt(3))
        R_f = dR @ world.R[f]
        centre = camera_centre(world.R[f], world.t[f]) + rng.normal(size=3) * noise.translation_sigma * np.median(d)
        t_f = -R_f @ centre
        pts_world = (cam_pts - t_f) @ R_f  # R_f^T (x_cam - t_f)
        points.append(pts_world)
        pix_both = np.zeros((2, keep.sum(), 2))
        pix_both[k] = pix[keep]
        obs = np.zeros((2, keep.sum()), bool)
        obs[k] = True
        pixels.append(pix_both)
        observed.append(obs)
        conf.append(np.ones(keep.sum()))
        R_noisy.append(R_f)
        t_noisy.append(t_f)
    frame = _random_similarity(rng, noise.scale_range)
    pts = frame.apply(torch.from_numpy(np.concatenate(points))).numpy()
    R_s, t_s = transform_cameras(frame, torch.from_numpy(np.stack(R_noisy)), torch.from_numpy(np.stack(t_noisy)))
    return SharedSpace(cut_frame=cut, K=world.K[list(frames)], R=R_s.numpy(), t=t_s.numpy(), points=pts,
                       pixels=np.concatenate(pixels, axis=1), observed=np.concatenate(observed, axis=1),
                       confidence=np.concatenate(conf), image_size=(h, w), source="simulated")


@dataclass(frozen=True)
class TrajectoryNoise:
    """Errors of the simulated intra-shot camera tracking.

    Attributes:
        rotation_drift_deg: rotation random-walk per frame (degrees, std) for moving cameras.
        translation_drift: translation random-walk per frame relative to the distance moved (std).
        scale_range: the trajectory's unknown scale is drawn log-uniformly in this range.
        map_points: size of the sparse scene map.
        static_threshold: a camera whose centre moves less than this (m) over the shot counts as static.
    """

    rotation_drift_deg: float = 0.02
    translation_drift: float = 0.02
    scale_range: tuple[float, float] = (0.5, 2.0)
    map_points: int = 500
    static_threshold: float = 1e-6


def simulate_camera_trajectory(video: SyntheticVideo, shot: int, noise: TrajectoryNoise = TrajectoryNoise(),
                               seed: int = 0) -> CameraTrajectory:
    """SIMULATED DROID-SLAM output for one shot: cameras in the shot's first-camera frame, unknown scale.

    A static camera gives the identity for every frame (``source="simulated:static"``), as a static
    detection does. The sparse map is built from the boundary frames' exact depth.
    """
    world = video.truth.world
    edges = [0, *world.cut_frames.tolist(), world.num_frames]
    a, b = edges[shot], edges[shot + 1]
    rng = np.random.default_rng([video.scene.config.seed, seed, shot, 13])
    R, t = world.R[a:b], world.t[a:b]
    centres = camera_centre(R, t)
    # The tracker's frame: the shot's first camera at the origin, scaled by an unknown factor.
    to_first = Similarity.from_numpy(1.0, R[0], t[0])  # world -> first camera coordinates
    scale = float(np.exp(rng.uniform(*np.log(noise.scale_range))))
    to_slam = Similarity.from_numpy(scale, np.eye(3), np.zeros(3)).compose(to_first)
    static = np.ptp(centres, axis=0).max() < noise.static_threshold and np.allclose(R, R[0], atol=1e-9)
    if static:
        R_s, t_s = np.tile(np.eye(3), (b - a, 1, 1)), np.zeros((b - a, 3))
    else:
        R_s, t_s = (x.numpy() for x in transform_cameras(to_slam, torch.from_numpy(R), torch.from_numpy(t)))
        # Drift: random walks in rotation and in the camera centre, zero at the first frame.
        steps = np.linalg.norm(np.diff(centres, axis=0), axis=1) * scale
        rot_walk = np.cumsum(rng.normal(size=(b - a, 3)) * np.deg2rad(noise.rotation_drift_deg) / np.sqrt(3), axis=0)
        rot_walk -= rot_walk[0]
        pos_walk = np.concatenate([np.zeros((1, 3)), np.cumsum(
            rng.normal(size=(b - a - 1, 3)) * noise.translation_drift * steps[:, None], axis=0)])
        c_s = camera_centre(R_s, t_s) + pos_walk
        R_s = axis_angle_to_matrix(rot_walk) @ R_s
        t_s = -(R_s @ c_s[..., None])[..., 0]
    points = _map_points(video, shot, noise.map_points, rng)
    if points is not None:
        points = to_slam.apply(torch.from_numpy(points)).numpy()
    return CameraTrajectory(shot_index=shot, start_frame=a, K=world.K[a], R=R_s, t=t_s, points=points,
                            source="simulated:static" if static else "simulated")


def _map_points(video: SyntheticVideo, shot: int, count: int, rng: np.random.Generator) -> np.ndarray | None:
    """World points of the room seen at the shot's boundary frames (people excluded), or None."""
    world = video.truth.world
    cuts = world.cut_frames.tolist()
    frames = []  # (cut index, which boundary frame) of this shot
    if shot > 0:
        frames.append((shot - 1, 1))
    if shot < len(cuts):
        frames.append((shot, 0))
    if not frames:
        return None
    out = []
    for c, k in frames:
        f = cuts[c] - 1 + k
        depth = video.boundary_depth[c, k]
        vs, us = np.nonzero(np.isfinite(depth) & (video.instance[f] < 0))
        pick = rng.choice(len(us), size=min(count, len(us)), replace=False)
        pix = np.stack([us[pick], vs[pick]], 1).astype(float)
        cam = unproject(pix, depth[vs[pick], us[pick]].astype(float), world.K[f])
        out.append((cam - world.t[f]) @ world.R[f])
    return np.concatenate(out)
