"""Propagation of the boundary alignment to every frame (paper §3.3), chained over any number of cuts.

Each shot's camera trajectory lives in its own tracking frame and scale. At an anchor frame, where the
same camera is known in the world (a refined boundary camera), the similarity ``S_k`` from the
tracking frame to the world follows in closed form: rotation and translation from the two poses of
that camera, scale from the depth of the tracker's map points against the shared space's point map
at the same pixels. ``S_k`` then carries every camera of the shot into the world.

Chaining: the world is the (metric) shared space of the first cut. Shot 0 is anchored at its last
frame, shot ``k > 0`` at its first frame (through cut ``k-1``); the shared space of cut ``k`` is placed
in the world by the camera of frame ``t_k - 1`` as shot ``k`` propagated it.

People: a track's camera-frame roots go to the world through each frame's world camera. Where the
track was aligned at a boundary, the alignment's correction is carried along the whole shot, in the
camera frame: a depth scale along the viewing ray, a residual offset and an orientation correction
(interpolated in time when the track was aligned at both ends of the shot).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from multithumbs.geometry import (Similarity, axis_angle_to_matrix, matrix_to_axis_angle, project,
                                  transform_cameras, world_to_camera)
from multithumbs.types import CameraTrajectory


def similarity_from_camera_pair(R_from: np.ndarray, t_from: np.ndarray, R_to: np.ndarray, t_to: np.ndarray,
                                scale: float = 1.0) -> Similarity:
    """Similarity ``S`` taking frame A to frame B, given one camera known in both.

    The camera is ``(R_from, t_from)`` in frame A, whose units are ``1/scale`` of B's, and
    ``(R_to, t_to)`` in frame B: ``x_B = R_to^T (scale (R_from x_A + t_from) - t_to)``.
    """
    rotation = R_to.T @ R_from
    translation = R_to.T @ (scale * t_from - t_to)
    return Similarity.from_numpy(scale, rotation, translation)


def trajectory_scale(trajectory: CameraTrajectory, frame: int, K: np.ndarray, R_world: np.ndarray,
                     t_world: np.ndarray, point_map: np.ndarray, point_valid: np.ndarray,
                     min_points: int = 10) -> float:
    """Metric scale of a trajectory: median ratio of shared-space to tracker depth at the map's pixels.

    Args:
        frame: shot-local index of the frame where both are known.
        K, R_world, t_world: that frame's camera in the (metric) shared space.
        point_map: ``(H, W, 3)`` metric scene points of that frame; point_valid ``(H, W)``.
    Returns:
        the scale, ``nan`` when fewer than ``min_points`` map points land on valid pixels.
    """
    if trajectory.points is None or len(trajectory.points) == 0:
        return float("nan")
    cam = world_to_camera(trajectory.points, trajectory.R[frame], trajectory.t[frame])
    front = cam[:, 2] > 1e-6
    uv = np.round(project(cam[front], trajectory.K)).astype(int)
    h, w = point_valid.shape
    inside = (uv[:, 0] >= 0) & (uv[:, 0] < w) & (uv[:, 1] >= 0) & (uv[:, 1] < h)
    uv, depth_track = uv[inside], cam[front][inside, 2]
    ok = point_valid[uv[:, 1], uv[:, 0]]
    if ok.sum() < min_points:
        return float("nan")
    world_pts = point_map[uv[ok, 1], uv[ok, 0]]
    depth_world = (world_pts @ R_world.T + t_world)[:, 2]
    ratio = depth_world / depth_track[ok]
    ratio = ratio[np.isfinite(ratio) & (ratio > 0)]
    return float(np.median(ratio)) if len(ratio) >= min_points else float("nan")


def place_trajectory(trajectory: CameraTrajectory, anchor: int, R_anchor: np.ndarray, t_anchor: np.ndarray,
                     scale: float) -> tuple[Similarity, np.ndarray, np.ndarray]:
    """World cameras of a whole shot from one anchor frame whose world camera is known.

    Returns:
        the tracking-to-world similarity, and ``R (T, 3, 3)``, ``t (T, 3)`` world cameras.
    """
    scale = scale if np.isfinite(scale) and scale > 0 else 1.0
    sim = similarity_from_camera_pair(trajectory.R[anchor], trajectory.t[anchor], R_anchor, t_anchor, scale)
    R, t = transform_cameras(sim, torch.from_numpy(trajectory.R.astype(np.float64)),
                             torch.from_numpy(trajectory.t.astype(np.float64)))
    return sim, R.numpy(), t.numpy()


@dataclass(frozen=True)
class RootCorrection:
    """A track's alignment correction at one boundary frame, in that frame's camera coordinates.

    Attributes:
        frame: shot-local frame index.
        depth_scale: aligned depth over estimated depth of the pelvis.
        offset: ``(3,)`` residual camera-frame offset after the depth scale.
        rotation: ``(3, 3)`` aligned orientation times the inverse estimated orientation.
    """

    frame: int
    depth_scale: float
    offset: np.ndarray
    rotation: np.ndarray


def root_correction(frame: int, orient_cam: np.ndarray, pelvis_cam: np.ndarray, orient_world: np.ndarray,
                    pelvis_world: np.ndarray, R: np.ndarray, t: np.ndarray) -> RootCorrection:
    """The correction that moves an estimated camera-frame root onto its aligned world root."""
    aligned_pelvis = R @ pelvis_world + t
    aligned_orient = R @ axis_angle_to_matrix(orient_world)
    depth_scale = float(aligned_pelvis[2] / pelvis_cam[2]) if pelvis_cam[2] > 1e-6 else 1.0
    return RootCorrection(frame, depth_scale, aligned_pelvis - depth_scale * pelvis_cam,
                          aligned_orient @ axis_angle_to_matrix(orient_cam).T)


def apply_corrections(orient_cam: np.ndarray, pelvis_cam: np.ndarray, corrections: list[RootCorrection],
                      default_scale: float = 1.0, correct_orientation: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Corrected camera-frame roots ``(T, 3)``, ``(T, 3)`` of one track.

    No correction: depth scaled by ``default_scale``. One: applied to every frame. Two (both ends of a
    shot): interpolated linearly in time between them (rotations along the geodesic), held outside.
    """
    t_count = orient_cam.shape[0]
    rot_cam = axis_angle_to_matrix(orient_cam)
    if not corrections:
        return orient_cam.copy(), pelvis_cam * default_scale
    corrections = sorted(corrections, key=lambda c: c.frame)
    first, last = corrections[0], corrections[-1]
    span = max(last.frame - first.frame, 1)
    w = np.clip((np.arange(t_count) - first.frame) / span, 0, 1) if len(corrections) > 1 else np.zeros(t_count)
    scale = (1 - w) * first.depth_scale + w * last.depth_scale
    offset = (1 - w)[:, None] * first.offset + w[:, None] * last.offset
    delta = matrix_to_axis_angle(last.rotation @ first.rotation.T)
    rotation = axis_angle_to_matrix(w[:, None] * delta) @ first.rotation
    orient = matrix_to_axis_angle(rotation @ rot_cam) if correct_orientation else orient_cam.copy()
    return orient, scale[:, None] * pelvis_cam + offset


def camera_to_world_roots(orient_cam: np.ndarray, pelvis_cam: np.ndarray, R: np.ndarray, t: np.ndarray
                          ) -> tuple[np.ndarray, np.ndarray]:
    """Roots ``(..., T, 3)`` in per-frame camera coordinates to the world, cameras ``R (T, 3, 3)``, ``t (T, 3)``."""
    Rt = np.swapaxes(R, -1, -2)
    orient = matrix_to_axis_angle(Rt @ axis_angle_to_matrix(orient_cam))
    pelvis = (Rt @ (pelvis_cam - t)[..., None])[..., 0]
    return orient, pelvis
