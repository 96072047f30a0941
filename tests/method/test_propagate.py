import numpy as np
import torch

from multithumbs.geometry import axis_angle_to_matrix, camera_centre, matrix_to_axis_angle, transform_cameras
from multithumbs.method.align import AlignedBoundary, point_maps
from multithumbs.method.propagate import (RootCorrection, apply_corrections, place_trajectory,
                                          similarity_from_camera_pair)
from multithumbs.pipeline import propagate
from multithumbs.synth.perception import true_track_people

from .conftest import apply, metric_frame


def _true_boundary(tiny, body, cut=0) -> AlignedBoundary:
    """What a perfect alignment returns: the truth expressed in the cut's metric shared space."""
    world = tiny.video.truth.world
    sim = tiny.space_from_world[cut]
    rigid = metric_frame(sim)
    s = float(sim.numpy()[0])
    frames = [int(world.cut_frames[cut]) - 1, int(world.cut_frames[cut])]
    R, t = transform_cameras(rigid, torch.from_numpy(world.R[frames]), torch.from_numpy(world.t[frames]))
    pelvis_rest = body.rest_joints(world.betas).double().numpy()[:, 0]
    tracks = [tiny.tracks[cut], tiny.tracks[cut + 1]]
    people = max(tr.num_people for tr in tracks)
    present = np.zeros((2, people), bool)
    index = np.full((2, people), -1)
    orient, pelvis = np.zeros((2, people, 3)), np.zeros((2, people, 3))
    for side, (tr, f) in enumerate(zip(tracks, frames)):
        local = f - tr.start_frame
        for i, p in enumerate(true_track_people(tr, tiny.video)):
            if tr.valid[i, local]:
                present[side, i], index[side, i] = True, i
                orient[side, i] = matrix_to_axis_angle(rigid.rotation.numpy() @ axis_angle_to_matrix(world.global_orient[p, f]))
                pelvis[side, i] = apply(rigid, world.transl[p, f] + pelvis_rest[p])
    maps, valid = point_maps(tiny.spaces[cut])
    return AlignedBoundary(cut_frame=frames[1], R=R.numpy(), t=t.numpy(), orient=orient, pelvis=pelvis,
                           present=present, track_index=index, scale=1 / s, point_map=maps / s, point_valid=valid)


def test_placing_a_trajectory_is_exact_with_a_known_scale(tiny):
    world = tiny.video.truth.world
    traj = tiny.trajectories[0]  # tracking frame: first camera at the origin, unknown scale
    a, b = tiny.shots.ranges[0]
    scale = float(np.linalg.norm(camera_centre(world.R[b - 1], world.t[b - 1]) - camera_centre(world.R[a], world.t[a]))
                  / np.linalg.norm(camera_centre(traj.R[-1], traj.t[-1])))
    _, R, t = place_trajectory(traj, b - a - 1, world.R[b - 1], world.t[b - 1], scale)
    np.testing.assert_allclose(R, world.R[a:b], atol=1e-9)
    np.testing.assert_allclose(camera_centre(R, t), camera_centre(world.R[a:b], world.t[a:b]), atol=1e-9)


def test_camera_pair_similarity_maps_one_camera_onto_the_other(tiny):
    rng = np.random.default_rng(0)
    R_a, t_a = axis_angle_to_matrix(rng.normal(size=3)), rng.normal(size=3)
    R_b, t_b = axis_angle_to_matrix(rng.normal(size=3)), rng.normal(size=3)
    sim = similarity_from_camera_pair(R_a, t_a, R_b, t_b, scale=2.0)
    x = rng.normal(size=(5, 3))  # the same point seen by the camera in both frames, camera coordinates scaled
    np.testing.assert_allclose(apply(sim, x) @ R_b.T + t_b, 2.0 * (x @ R_a.T + t_a), atol=1e-12)


def test_propagation_is_exact_on_noise_free_input(tiny, body):
    aligned = [_true_boundary(tiny, body)]
    placement = propagate(tiny.shots, tiny.tracks, tiny.trajectories, aligned, body)
    world = tiny.video.truth.world
    rigid = metric_frame(tiny.space_from_world[0])
    R_true, t_true = transform_cameras(rigid, torch.from_numpy(world.R), torch.from_numpy(world.t))
    np.testing.assert_allclose(placement.R, R_true.numpy(), atol=1e-6)
    # Both shots dolly: their tracking scale is found from the map's depth (sampled at whole pixels).
    np.testing.assert_allclose(camera_centre(placement.R, placement.t), camera_centre(R_true.numpy(), t_true.numpy()),
                               atol=5e-3)
    pelvis_rest = body.rest_joints(world.betas).double().numpy()[:, 0]
    for k, (a, b) in enumerate(tiny.shots.ranges):
        for i, p in enumerate(true_track_people(tiny.tracks[k], tiny.video)):
            v = tiny.tracks[k].valid[i]
            expected = apply(rigid, world.transl[p, a:b][v] + pelvis_rest[p])
            np.testing.assert_allclose(placement.pelvis[k][i, v], expected, atol=5e-3)
            np.testing.assert_allclose(axis_angle_to_matrix(placement.orient[k][i, v]),
                                       rigid.rotation.numpy() @ axis_angle_to_matrix(world.global_orient[p, a:b][v]),
                                       atol=1e-6)


def test_corrections_scale_depth_offset_and_optionally_rotate():
    rng = np.random.default_rng(3)
    orient, pelvis = rng.normal(0, 0.3, (5, 3)), rng.uniform([-1, -1, 3], [1, 1, 6], (5, 3))
    turn = axis_angle_to_matrix(np.array([0.0, 0.2, 0.0]))
    fix = RootCorrection(frame=4, depth_scale=1.1, offset=np.array([0.01, 0.0, 0.0]), rotation=turn)
    o, p = apply_corrections(orient, pelvis, [fix])
    np.testing.assert_allclose(p, 1.1 * pelvis + [0.01, 0, 0])
    np.testing.assert_allclose(axis_angle_to_matrix(o), turn @ axis_angle_to_matrix(orient), atol=1e-12)
    o_kept, p_kept = apply_corrections(orient, pelvis, [fix], correct_orientation=False)
    np.testing.assert_allclose(o_kept, orient)
    np.testing.assert_allclose(p_kept, p)
    # No correction: only the shot's default depth scale.
    o_none, p_none = apply_corrections(orient, pelvis, [], default_scale=0.9)
    np.testing.assert_allclose(p_none, 0.9 * pelvis)
