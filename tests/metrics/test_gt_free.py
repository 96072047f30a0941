import numpy as np
import pytest

from multithumbs.errors import InputError
from multithumbs.geometry import axis_angle_to_matrix, intrinsics_from_fov, look_at, project_points
from multithumbs.metrics.gt_free import (
    FOOT_JOINTS, SMPL_FOOT_VERTICES, cross_shot_pck, estimate_up, foot_points, foot_sliding, jitter,
)
from tests.metrics import reference
from tests.metrics.conftest import SKELETON


def test_jitter_zero_for_constant_velocity_and_hand_computed_for_a_cubic():
    t = np.arange(12.0)[None, :, None, None]
    valid = np.ones((1, 12), bool)
    linear = 0.3 + 0.05 * t * np.ones((1, 1, 24, 3))
    assert jitter(linear, valid, fps=30.0).mean() == pytest.approx(0.0, abs=1e-9)
    quadratic = 0.01 * t ** 2 * np.array([1.0, 0.0, 0.0])
    assert jitter(quadratic, valid, fps=30.0).mean() == pytest.approx(0.0, abs=1e-9)
    # x = c t^3 has third difference 6c per frame^3: jitter = 6c * fps^3 / 10.
    cubic = 0.001 * t ** 3 * np.array([0.0, 1.0, 0.0])
    assert jitter(cubic, valid, fps=30.0).mean() == pytest.approx(6 * 0.001 * 30.0 ** 3 / 10)
    with pytest.raises(InputError, match="fps"):
        jitter(cubic, valid, fps=0.0)


def test_jitter_runs_over_compressed_valid_frames_hand_computed():
    # x = c t^3 (frame index t), frame 5 missing: compressed frames 0 1 2 3 4 6 7 8 9, windows start at
    # packed positions 0..5. Third differences of t^3 over (0,1,2,3), (1,2,3,4) are 6; over (2,3,4,6)
    # 216 - 3*64 + 3*27 - 8 = 97; over (3,4,6,7) 343 - 648 + 192 - 27 = -140; over (4,6,7,8)
    # 512 - 1029 + 648 - 64 = 67; over (6,7,8,9) 6.
    c, fps = 0.001, 30.0
    t = np.arange(10.0)
    joints = np.zeros((1, 10, 24, 3))
    joints[0, :, :, 2] = c * t[:, None] ** 3
    valid = np.ones((1, 10), bool)
    valid[0, 5] = False
    samples = jitter(joints, valid, fps)
    expected = np.array([6.0, 6.0, 97.0, 140.0, 67.0, 6.0]) * c * fps ** 3 / 10.0
    np.testing.assert_allclose(np.sort(samples.scored), np.sort(expected), rtol=1e-12)
    np.testing.assert_allclose(np.sort(samples.scored), np.sort(reference.jitter_values(joints, valid, fps)),
                               rtol=1e-12)
    # Windows whose first and last frames lie in different shots are left out on request: with a cut
    # at frame 3 the windows starting at packed 0, 1 and 2 (frames 0-3, 1-4, 2-6) span it.
    assert jitter(joints, valid, fps, cut_frames=[3], include_cuts=False).count == 3


def _pck_scene(rng):
    """Two people, two frames either side of a cut at 1, two different cameras."""
    K = np.stack([intrinsics_from_fov(640, 480, 60.0)] * 2)
    R, t = look_at(np.array([[0.0, -6.0, 1.5], [4.0, -4.0, 1.8]]), np.array([[0.0, 0.0, 1.0]] * 2))
    stand = axis_angle_to_matrix(np.array([np.pi / 2, 0.0, 0.0]))
    body = SKELETON @ stand.T + np.array([0.0, 0.0, 0.95])
    joints = np.stack([body + [x, 0.0, 0.0] for x in (-0.8, 0.8)])[:, None].repeat(2, axis=1)  # (2, 2, 24, 3)
    uv = project_points(joints, K, R, t)
    keypoints = np.concatenate([uv, np.ones((*uv.shape[:-1], 1))], axis=-1)
    return joints, keypoints, K, R, t


def test_cross_shot_pck_perfect_and_shifted():
    rng = np.random.default_rng(1)
    joints, keypoints, K, R, t = _pck_scene(rng)
    valid = np.ones((2, 2), bool)
    perfect = cross_shot_pck(joints, valid, keypoints, K, R, t, [1])
    assert perfect.percentage() == pytest.approx(100.0)
    assert perfect.forward.count == 2 * 24
    # The keypoints after the cut move 100 px: forward fails, backward still projects correctly.
    shifted = keypoints.copy()
    shifted[:, 1, :, 0] += 100.0
    result = cross_shot_pck(joints, valid, shifted, K, R, t, [1])
    assert result.forward.mean() == pytest.approx(0.0)
    assert result.percentage() == pytest.approx(50.0)
    # Low-confidence keypoints are not scored.
    shifted[:, 1, :, 2] = 0.5
    assert cross_shot_pck(joints, valid, shifted, K, R, t, [1]).percentage() == pytest.approx(100.0)
    # A person absent on one side is not scored.
    valid[0, 0] = False
    assert cross_shot_pck(joints, valid, keypoints, K, R, t, [1]).forward.count == 24


def test_cross_shot_pck_threshold_scales_with_alpha():
    joints, keypoints, K, R, t = _pck_scene(np.random.default_rng(2))
    size = np.ptp(keypoints[0, 1, :, :2], axis=0).max()
    nudged = keypoints.copy()
    nudged[0, 1, :, 0] += 0.07 * size  # inside 0.1 * size, outside 0.05 * size
    valid = np.ones((2, 2), bool)
    loose = cross_shot_pck(joints, valid, nudged, K, R, t, [1], alpha=0.1)
    strict = cross_shot_pck(joints, valid, nudged, K, R, t, [1], alpha=0.05)
    assert loose.forward.mean() == pytest.approx(100.0)
    assert strict.forward.mean() == pytest.approx(50.0)
    with pytest.raises(InputError, match="keypoints2d"):
        cross_shot_pck(joints, valid, nudged[:, :, :17], K, R, t, [1])


def test_foot_sliding_planted_and_sliding():
    t = 8
    up = np.array([0.0, 0.0, 1.0])
    feet = np.zeros((1, t, 2, 3))
    feet[0, :, 1, 2] = 0.3  # second foot in the air: never in contact
    feet[0, :, 1, 0] = 0.1 * np.arange(t)
    valid = np.ones((1, t), bool)
    planted = foot_sliding(feet, valid, up)
    assert planted.mean() == pytest.approx(0.0) and planted.count == t - 1
    sliding = feet.copy()
    sliding[0, :, 0, 1] = 0.004 * np.arange(t)  # 4 mm per frame along the floor
    sliding[0, :, 0, 2] = 0.001 * np.arange(t)  # vertical motion does not count as sliding
    assert foot_sliding(sliding, valid, up).mean() == pytest.approx(4.0)
    assert foot_sliding(sliding, valid, up, cut_frames=[3]).count == t - 2


def test_foot_points_selection():
    joints = np.random.default_rng(3).normal(size=(2, 24, 3))
    smpl_vertices = np.random.default_rng(4).normal(size=(2, 6890, 3))
    np.testing.assert_array_equal(foot_points(joints, smpl_vertices), smpl_vertices[:, SMPL_FOOT_VERTICES])
    np.testing.assert_array_equal(foot_points(joints, smpl_vertices[:, :100]), joints[:, FOOT_JOINTS])
    np.testing.assert_array_equal(foot_points(joints, smpl_vertices, [5, 6]), smpl_vertices[:, [5, 6]])
    np.testing.assert_array_equal(foot_points(joints, None), joints[:, FOOT_JOINTS])


def test_estimate_up_of_standing_bodies():
    stand = axis_angle_to_matrix(np.array([np.pi / 2, 0.0, 0.0]))
    joints = (SKELETON @ stand.T)[None, None].repeat(3, axis=1)
    np.testing.assert_allclose(estimate_up(joints, np.ones((1, 3), bool)), [0.0, 0.0, 1.0], atol=1e-12)
    with pytest.raises(InputError, match="valid"):
        estimate_up(joints, np.zeros((1, 3), bool))
