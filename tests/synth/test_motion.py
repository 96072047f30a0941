import numpy as np
from scipy.spatial.transform import Rotation

from multithumbs.synth.motion import (BODY_TO_WORLD, MotionConfig, motion_to_smpl, simulate_walk, straight_walk,
                                      walk_abreast)


def _walk(seed=0, frames=300, **kw):
    rng = np.random.default_rng(seed)
    return simulate_walk(np.zeros(2), [np.array([1.5, 0.5]), np.array([-1.0, 1.0])], frames, 30.0, rng, **kw)


def test_walk_speed_and_turning_are_human():
    m = _walk()
    speed = np.linalg.norm(np.diff(m.position, axis=0), axis=1) * 30.0
    assert speed.max() <= 1.8 + 1e-9
    assert 0.3 < speed.mean() < 1.6
    turn = np.abs(np.diff(np.unwrap(m.heading))) * 30.0
    assert turn.max() <= MotionConfig().turn_rate + 1e-9
    # It reaches the first waypoint.
    assert np.linalg.norm(m.position - [1.5, 0.5], axis=1).min() < 0.2


def test_walk_is_reproducible_from_seed():
    a, b, c = _walk(3), _walk(3), _walk(4)
    np.testing.assert_array_equal(a.position, b.position)
    assert not np.allclose(a.position, c.position)


def test_pauses_stop_the_legs():
    m = _walk(seed=1, frames=900, config=MotionConfig(stand_probability=1.0))
    still = np.linalg.norm(np.diff(m.position, axis=0), axis=1) == 0
    assert still.any()
    assert m.gait_amount[1:][still].min() == 0.0  # legs settle during a pause
    assert np.all(m.gait_amount[1:][~still] > 0.0)


def test_smpl_pose_is_upright_and_faces_heading():
    m = _walk(frames=60)
    orient, pose = motion_to_smpl(m)
    assert orient.shape == (60, 3) and pose.shape == (60, 23, 3)
    R = Rotation.from_rotvec(orient).as_matrix()
    np.testing.assert_allclose(R[:, :, 1], np.tile([0, 0, 1.0], (60, 1)), atol=1e-9)  # body up = world up
    forward = R[:, :2, 2]  # body +z in the world
    np.testing.assert_allclose(forward, np.stack([np.cos(m.heading), np.sin(m.heading)], 1), atol=1e-9)
    np.testing.assert_allclose(BODY_TO_WORLD @ BODY_TO_WORLD.T, np.eye(3))
    # Walking swings the legs in opposition.
    hips = np.abs(pose[:, [0, 1], 0]).max(axis=0)
    assert np.all(hips > np.deg2rad(10))


def test_straight_walk_passes_through_at_the_time_and_stands_at_the_path_ends():
    rng = np.random.default_rng(0)
    m = straight_walk(np.array([0.5, -0.2]), np.deg2rad(30), 1.0, 90, 30.0, 1.2, rng, path=(-0.6, 1.5))
    np.testing.assert_allclose(m.position[30], [0.5, -0.2], atol=1e-9)  # at the point at t = 1 s
    np.testing.assert_allclose(m.heading, np.deg2rad(30))
    step = np.linalg.norm(np.diff(m.position, axis=0), axis=1) * 30.0
    walking = step > 0
    np.testing.assert_allclose(step[walking][1:-1], 1.2, atol=1e-9)  # constant speed (first, last step partial)
    assert step.max() <= 1.2 + 1e-9
    assert not walking[0] and not walking[-1]  # stands at both ends of the path
    along = (m.position - [0.5, -0.2]) @ [np.cos(np.deg2rad(30)), np.sin(np.deg2rad(30))]
    np.testing.assert_allclose([along.min(), along.max()], [-0.6, 1.5], atol=1e-9)
    assert m.gait_amount[0] == 0.0 and m.gait_amount[-1] == 0.0 and m.gait_amount[30] == 1.0
    assert np.all(m.gesture == 0)


def test_walk_abreast_shares_heading_and_speed_side_by_side():
    rng = np.random.default_rng(1)
    left, right = walk_abreast(np.zeros(2), 0.4, 1.5, 1.2, 90, 30.0, rng, path=(-1.0, 1.0))
    np.testing.assert_array_equal(left.heading, right.heading)
    offset = left.position - right.position
    np.testing.assert_allclose(np.linalg.norm(offset, axis=1), 1.2, atol=1e-9)
    # side by side: the offset is across the heading, to the left
    np.testing.assert_allclose(offset @ [np.cos(0.4), np.sin(0.4)], 0.0, atol=1e-9)
    assert np.all(offset @ [-np.sin(0.4), np.cos(0.4)] > 0)
    np.testing.assert_allclose(np.diff(left.position, axis=0), np.diff(right.position, axis=0), atol=1e-12)
    np.testing.assert_allclose(0.5 * (left.position[45] + right.position[45]), [0.0, 0.0], atol=1e-9)
    assert not np.allclose(left.gait_phase, right.gait_phase)  # each walks in their own step
