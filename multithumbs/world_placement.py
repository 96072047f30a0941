"""Every camera and every track's root in one world frame, cut by cut (paper §3.3; the chain's step 3).

The first cut's metric shared space is the world; shot ``k`` is placed through cut ``k - 1`` (its first
frame's aligned camera) and carries cut ``k``'s space into the world by its last frame's camera, so the
cuts chain. The closed-form pieces (trajectory scale and placement, root corrections) are
:mod:`multithumbs.method.propagate`; this module applies them to a whole video.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
import torch

from multithumbs.geometry import (Similarity, axis_angle_to_matrix, matrix_to_axis_angle, reexpress_for_intrinsics,
                                  transform_cameras)
from multithumbs.method.align import AlignedBoundary
from multithumbs.method.propagate import (apply_corrections, camera_to_world_roots, place_trajectory,
                                          root_correction, similarity_from_camera_pair, trajectory_scale)
from multithumbs.types import CameraTrajectory, PersonTracks, Shots


@dataclass(frozen=True)
class Placement:
    """Every shot's cameras and tracks in one world frame.

    Attributes:
        R: ``(T, 3, 3)``; t: ``(T, 3)`` world cameras of all frames; K: ``(T, 3, 3)``.
        orient: per shot ``(P_s, T_s, 3)`` world root orientations.
        transl: per shot ``(P_s, T_s, 3)`` world SMPL translations.
        pelvis: per shot ``(P_s, T_s, 3)`` world pelvis positions.
        trajectory_scales: ``(S,)`` metric scale found for each shot's tracking (nan: none found, 1 used).
        space_to_world: per cut ``(4, 4)`` similarity matrix from the cut's metric shared space to the world.
        distance_reliable: ``(C,)`` bool, the cut's boundary cameras came from the scene or the people
            (``AlignedBoundary.cameras_from`` not ``"none"``): root distances across it mean something.
            None: all (placements stored before this field).
    """

    R: np.ndarray
    t: np.ndarray
    K: np.ndarray
    orient: tuple[np.ndarray, ...]
    transl: tuple[np.ndarray, ...]
    pelvis: tuple[np.ndarray, ...]
    trajectory_scales: np.ndarray
    space_to_world: np.ndarray
    distance_reliable: np.ndarray | None = None


def _sim_matrix(sim: Similarity) -> np.ndarray:
    s, R, t = sim.numpy()
    m = np.eye(4)
    m[:3, :3], m[:3, 3] = float(s) * R, t
    return m


def _apply_matrix(m: np.ndarray, points: np.ndarray) -> np.ndarray:
    return points @ m[:3, :3].T + m[:3, 3]


def propagate(shots: Shots, tracks: Sequence[PersonTracks], trajectories: Sequence[CameraTrajectory],
              aligned: Sequence[AlignedBoundary], body, independent: bool = False,
              propagate_orientation: bool = False) -> Placement:
    """Cameras and people of every shot in the world frame (the first cut's metric shared space).

    ``propagate_orientation=False`` carries only the aligned root position along a shot and keeps the
    estimator's camera-relative orientation (see :class:`MethodConfig`).
    """
    edges = [r[0] for r in shots.ranges] + [shots.num_frames]
    n_shots = shots.num_shots
    T = shots.num_frames
    R_all, t_all, K_all = np.zeros((T, 3, 3)), np.zeros((T, 3)), np.zeros((T, 3, 3))
    space_to_world = np.tile(np.eye(4), (len(aligned), 1, 1))
    scales = np.full(n_shots, np.nan)
    shot_R, shot_t = [], []
    for k in range(n_shots):
        traj = trajectories[k]
        a, b = edges[k], edges[k + 1]
        if independent or not aligned:
            # Without a cut (one shot) there is no shared space: the world is the shot's own SLAM frame.
            R_k, t_k = traj.R.astype(np.float64), traj.t.astype(np.float64)
        else:
            if k == 0:
                cut, side, anchor = aligned[0], 0, b - a - 1
                to_world = np.eye(4)
            else:
                cut, side, anchor = aligned[k - 1], 1, 0
                to_world = space_to_world[k - 1]
            R_anchor, t_anchor = _camera_in_world(cut.R[side], cut.t[side], to_world)
            maps = _map_in_world(cut.point_map[side], cut.point_valid[side], to_world)
            scales[k] = trajectory_scale(traj, anchor, traj.K, R_anchor, t_anchor, maps, cut.point_valid[side])
            _, R_k, t_k = place_trajectory(traj, anchor, R_anchor, t_anchor, scales[k])
            if k < len(aligned) and k > 0:
                # Place cut k's space in the world by the camera of frame t_k - 1 as this shot propagated it.
                sim = similarity_from_camera_pair(aligned[k].R[0], aligned[k].t[0], R_k[-1], t_k[-1])
                space_to_world[k] = _sim_matrix(sim)
        R_all[a:b], t_all[a:b], K_all[a:b] = R_k, t_k, traj.K
        shot_R.append(R_k)
        shot_t.append(t_k)

    orients, transls, pelvises = [], [], []
    for k in range(n_shots):
        tr = tracks[k]
        pelvis_rest = body.rest_pelvis(tr.betas)                                # (P, 3)
        pelvis_cam = reexpress_for_intrinsics(tr.transl + pelvis_rest[:, None], tr.K, trajectories[k].K)
        corrections = {i: [] for i in range(tr.num_people)}
        if not independent:
            for c, side, frame in ((k - 1, 1, 0), (k, 0, tr.num_frames - 1)):
                if not 0 <= c < len(aligned):
                    continue
                cut = aligned[c]
                for j in np.nonzero(cut.present[side])[0]:
                    i = int(cut.track_index[side, j])
                    f = frame if cut.track_frame is None else int(cut.track_frame[side, j])
                    m = space_to_world[c]
                    rot = m[:3, :3] / np.cbrt(np.linalg.det(m[:3, :3]))
                    orient_w = matrix_to_axis_angle(rot @ axis_angle_to_matrix(cut.orient[side, j]))
                    pelvis_w = _apply_matrix(m, cut.pelvis[side, j])
                    corrections[i].append(root_correction(f, tr.global_orient[i, f], pelvis_cam[i, f],
                                                          orient_w, pelvis_w, shot_R[k][f], shot_t[k][f]))
        known = [c.depth_scale for cs in corrections.values() for c in cs]
        default_scale = float(np.median(known)) if known else 1.0
        orient_k = np.zeros_like(tr.global_orient)
        pelvis_k = np.zeros_like(pelvis_cam)
        for i in range(tr.num_people):
            o_c, p_c = apply_corrections(tr.global_orient[i], pelvis_cam[i], corrections[i], default_scale,
                                         correct_orientation=propagate_orientation)
            orient_k[i], pelvis_k[i] = camera_to_world_roots(o_c, p_c, shot_R[k], shot_t[k])
        orients.append(orient_k)
        pelvises.append(pelvis_k)
        transls.append(pelvis_k - pelvis_rest[:, None])
    reliable = np.array([a.cameras_from != "none" for a in aligned], bool) if not independent \
        else np.zeros(shots.num_shots - 1, bool)
    return Placement(R_all, t_all, K_all, tuple(orients), tuple(transls), tuple(pelvises), scales, space_to_world,
                     reliable)


def _camera_in_world(R: np.ndarray, t: np.ndarray, space_to_world: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A camera of a shared space re-expressed in the world (the space-to-world map is SE(3))."""
    sim = Similarity.from_numpy(1.0, space_to_world[:3, :3], space_to_world[:3, 3])
    R_w, t_w = transform_cameras(sim, torch.from_numpy(np.asarray(R, float)), torch.from_numpy(np.asarray(t, float)))
    return R_w.numpy(), t_w.numpy()


def _map_in_world(point_map: np.ndarray, valid: np.ndarray, space_to_world: np.ndarray) -> np.ndarray:
    return np.where(valid[..., None], _apply_matrix(space_to_world, point_map), 0.0)


# ----------------------------------------------------------------------------------------------------
# 4. Re-identification
