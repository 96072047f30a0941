import copy

import numpy as np
import pytest
import torch

from multithumbs.errors import InputError
from multithumbs.geometry import Similarity, camera_centre, look_at, transform_cameras
from multithumbs.metrics.alignment import apply_similarity
from multithumbs.metrics.camera import absolute_trajectory_error, centre_rank
from tests.metrics.conftest import random_similarity


def _evo_ape(est: np.ndarray, ref: np.ndarray) -> tuple[float, float]:
    """evo's APE (translation part) after Sim(3) alignment: RMSE and mean."""
    from evo.core import metrics, trajectory

    quat = np.tile([1.0, 0.0, 0.0, 0.0], (len(est), 1))
    stamps = np.arange(len(est), dtype=float)
    traj_ref = trajectory.PoseTrajectory3D(positions_xyz=ref, orientations_quat_wxyz=quat, timestamps=stamps)
    traj_est = trajectory.PoseTrajectory3D(positions_xyz=est, orientations_quat_wxyz=quat, timestamps=stamps)
    traj_est = copy.deepcopy(traj_est)
    traj_est.align(traj_ref, correct_scale=True)
    ape = metrics.APE(metrics.PoseRelation.translation_part)
    ape.process_data((traj_ref, traj_est))
    return ape.get_statistic(metrics.StatisticsType.rmse), ape.get_statistic(metrics.StatisticsType.mean)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_ate_agrees_with_evo(seed):
    rng = np.random.default_rng(seed)
    true = np.cumsum(rng.normal(size=(60, 3)) * 0.1, axis=0)
    est = apply_similarity(random_similarity(rng), true) + rng.normal(size=true.shape) * 0.05
    ours = absolute_trajectory_error(est, true)
    rmse, mean = _evo_ape(est, true)
    assert not ours.fallback and ours.centre_rank == 3
    assert rmse > 1e-3  # a real error, not a trivial zero
    assert ours.rmse == pytest.approx(rmse, abs=1e-6)
    assert ours.mean == pytest.approx(mean, abs=1e-6)


def test_ate_zero_under_global_similarity():
    rng = np.random.default_rng(3)
    true = rng.normal(size=(30, 3))
    est = apply_similarity(random_similarity(rng), true)
    ours = absolute_trajectory_error(est, true)
    assert ours.rmse < 1e-9 and ours.mean < 1e-9
    # The alignment maps the prediction back into the true world.
    np.testing.assert_allclose(apply_similarity(ours.alignment, est), true, atol=1e-9)


def test_ate_zero_when_the_cameras_move_with_the_world():
    # A Sim(3) of the whole world, cameras included, moves the centres as points.
    rng = np.random.default_rng(4)
    eyes = np.cumsum(rng.normal(size=(25, 3)), axis=0)
    R, t = look_at(eyes, eyes + rng.normal(size=(25, 3)))
    sim = random_similarity(rng)
    R_moved, t_moved = transform_cameras(sim, torch.from_numpy(R), torch.from_numpy(t))
    centres = camera_centre(R_moved.numpy(), t_moved.numpy())
    np.testing.assert_allclose(centres, apply_similarity(sim, eyes), atol=1e-9)
    assert absolute_trajectory_error(centres, camera_centre(R, t)).rmse < 1e-9


def test_ate_degenerate_uses_the_fallback_and_says_so():
    # Static cameras per shot: two distinct centres only.
    true = np.repeat(np.array([[0.0, -5.0, 1.5], [4.0, -3.0, 1.8]]), 10, axis=0)
    offset = np.array([1.0, 2.0, 3.0])
    est = true + offset
    assert centre_rank(est, true) == 1
    with pytest.raises(InputError, match="degenerate"):
        absolute_trajectory_error(est, true)
    fallback = Similarity.from_numpy(1.0, np.eye(3), -offset)
    ours = absolute_trajectory_error(est, true, fallback_alignment=fallback)
    assert ours.fallback and ours.centre_rank == 1
    assert ours.rmse == pytest.approx(0.0, abs=1e-12)
    wrong = Similarity.from_numpy(1.0, np.eye(3), np.zeros(3))
    assert absolute_trajectory_error(est, true, fallback_alignment=wrong).rmse == pytest.approx(np.linalg.norm(offset))


def test_centre_rank_of_a_single_point_is_zero():
    assert centre_rank(np.ones((5, 3)), np.ones((5, 3))) == 0
    with pytest.raises(InputError, match="pred_centres"):
        absolute_trajectory_error(np.zeros((4, 3)), np.zeros((5, 3)))
