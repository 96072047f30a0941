import dataclasses

import numpy as np
import pytest
import torch
from scipy.spatial.transform import Rotation

from multithumbs.errors import InputError
from multithumbs.geometry import intrinsics_from_fov, matrix_to_axis_angle, project, umeyama
from multithumbs.perception.body_fit import FACING_CAMERA, BodyFitConfig, fit_bodies

BLAZEPOSE_JOINTS = [0, 1, 2, 4, 5, 7, 8, 16, 17, 18, 19, 20, 21]
"""SMPL joints the BlazePose mapping gives: pelvis, hips, knees, ankles, shoulders, elbows, wrists."""

K = intrinsics_from_fov(640, 360, 60)
NOISE_PX, NOISE_M = 2.5, 0.02
MEAN_NOISE_PX = NOISE_PX * np.sqrt(np.pi / 2)
"""Mean length of a 2D noise vector with ``NOISE_PX`` per coordinate (Rayleigh)."""


def _scene(body, people=4, frames=60, seed=0, noise_px=NOISE_PX, noise_m=NOISE_M):
    """Detections of people moving smoothly 3-6 m in front of a 60° camera at 640x360, and their true joints.

    Poses: limbs (hips, knees, ankles, shoulders, elbows, wrists) within ~0.25 rad of a standing pose with
    the arms down, the rest within ~0.1 rad, all swaying; any yaw, pitch within 0.3 rad; small betas.
    """
    rng = np.random.default_rng(seed)
    t = np.arange(frames)[None, :, None] / 30.0
    spread = np.full((23, 3), 0.1)
    spread[[0, 1, 3, 4, 6, 7, 15, 16, 17, 18, 19, 20]] = 0.25
    base = rng.normal(0, 1, (people, 1, 69)) * spread.reshape(69)
    base[:, 0, 15 * 3 + 2] -= 1.1                                  # left shoulder: arm down
    base[:, 0, 16 * 3 + 2] += 1.1                                  # right shoulder
    sway = rng.normal(0, 0.15, (people, 1, 69)) * np.sin(2 * np.pi * rng.uniform(0.3, 1.0, (people, 1, 69)) * t
                                                         + rng.uniform(0, 2 * np.pi, (people, 1, 69)))
    pose = (base + sway).reshape(people, frames, 23, 3)
    yaw = rng.uniform(-np.pi, np.pi, (people, 1)) + 0.3 * np.sin(t[..., 0])
    pitch = np.broadcast_to(rng.uniform(-0.3, 0.3, (people, 1)), yaw.shape)
    body_to_camera = Rotation.from_matrix(FACING_CAMERA) * Rotation.from_euler(
        "YX", np.stack([yaw, pitch], -1).reshape(-1, 2))
    orient = body_to_camera.as_rotvec().reshape(people, frames, 3)
    depth = rng.uniform(3, 6, (people, 1)) + 0.2 * np.sin(0.5 * t[..., 0])
    transl = np.stack([rng.uniform(-0.4, 0.4, (people, 1)) * depth, np.full_like(depth, 0.2), depth], -1)
    betas = rng.normal(0, 0.5, (people, 10))
    joints = body.joints(orient, pose, betas, transl).double().numpy()
    confidence = np.zeros(joints.shape[:-1] + (1,))
    confidence[..., BLAZEPOSE_JOINTS, :] = 1.0
    pixels = project(joints, K) + rng.normal(0, noise_px, joints.shape[:-1] + (2,))
    relative = joints - 0.5 * (joints[..., 1:2, :] + joints[..., 2:3, :]) + rng.normal(0, noise_m, joints.shape)
    return np.concatenate([pixels, confidence], -1), np.concatenate([relative, confidence], -1), joints


def _joints(body, fit):
    return body.joints(fit.global_orient, fit.body_pose, fit.betas, fit.transl).double().numpy()


def _acceleration(joints):
    return np.linalg.norm(joints[:, 2:] - 2 * joints[:, 1:-1] + joints[:, :-2], axis=-1).mean()


@pytest.fixture(scope="module")
def scene(body):
    return _scene(body)


@pytest.fixture(scope="module")
def fitted(scene, body):
    keypoints, joints3d, _ = scene
    return fit_bodies(keypoints, joints3d, np.ones(keypoints.shape[:2], bool), K, body)


def test_shapes_and_invalid_frames_come_out_finite(body):
    keypoints, joints3d, _ = _scene(body, people=2, frames=12, seed=1)
    valid = np.ones((2, 12), bool)
    valid[1, [0, 1, 5, 6, 7, 11]] = False
    keypoints[~valid] = np.nan                                    # whatever invalid frames hold is ignored
    joints3d[1, 3, 3:, 3] = keypoints[1, 3, 3:, 2] = 0.0          # only the pelvis and hips: too few to orient
    fit = fit_bodies(keypoints, joints3d, valid, K, body, BodyFitConfig(iterations=20))
    assert fit.global_orient.shape == (2, 12, 3) and fit.body_pose.shape == (2, 12, 23, 3)
    assert fit.betas.shape == (2, 10) and fit.transl.shape == (2, 12, 3) and fit.reprojection_px.shape == (2, 12)
    for array in (fit.global_orient, fit.body_pose, fit.betas, fit.transl):
        assert np.isfinite(array).all()
    np.testing.assert_array_equal(np.isnan(fit.reprojection_px), ~valid)
    # Invalid frames hold their nearest valid frame (ties: the earlier).
    for frame, nearest in ((0, 2), (1, 2), (5, 4), (6, 4), (7, 8), (11, 10)):
        np.testing.assert_array_equal(fit.transl[1, frame], fit.transl[1, nearest])
        np.testing.assert_array_equal(fit.body_pose[1, frame], fit.body_pose[1, nearest])


def test_no_people_and_people_never_seen(body):
    fit = fit_bodies(np.zeros((0, 5, 24, 3)), np.zeros((0, 5, 24, 4)), np.zeros((0, 5), bool), K, body)
    assert fit.global_orient.shape == (0, 5, 3) and fit.body_pose.shape == (0, 5, 23, 3)
    assert fit.betas.shape == (0, 10) and fit.transl.shape == (0, 5, 3) and fit.reprojection_px.shape == (0, 5)
    keypoints, joints3d, _ = _scene(body, people=2, frames=4, seed=2)
    valid = np.array([[True] * 4, [False] * 4])
    fit = fit_bodies(keypoints, joints3d, valid, K, body, BodyFitConfig(iterations=5))
    assert np.isfinite(fit.transl).all() and np.isnan(fit.reprojection_px[1]).all()
    np.testing.assert_allclose(fit.global_orient[1], np.tile(matrix_to_axis_angle(FACING_CAMERA), (4, 1)))


@pytest.mark.parametrize("argument, change", [
    ("keypoints2d", lambda a: {**a, "keypoints2d": a["keypoints2d"][..., :2]}),
    ("keypoints2d", lambda a: {**a, "keypoints2d": a["keypoints2d"][:, :, :17]}),
    ("keypoints2d", lambda a: {**a, "keypoints2d": np.where(np.arange(3) == 0, np.nan, a["keypoints2d"])}),
    ("keypoints2d", lambda a: {**a, "keypoints2d": a["keypoints2d"] * [1, 1, 3]}),
    ("joints3d", lambda a: {**a, "joints3d": a["joints3d"][..., :3]}),
    ("joints3d", lambda a: {**a, "joints3d": a["joints3d"][:1]}),
    ("joints3d", lambda a: {**a, "joints3d": np.full_like(a["joints3d"], np.inf)}),
    ("valid", lambda a: {**a, "valid": a["valid"].astype(int)}),
    ("valid", lambda a: {**a, "valid": a["valid"][:, :2]}),
    ("K", lambda a: {**a, "K": a["K"][:2]}),
    ("K", lambda a: {**a, "K": a["K"] * np.nan}),
    ("K", lambda a: {**a, "K": -a["K"]}),
])
def test_bad_input_names_the_argument(body, argument, change):
    good = {"keypoints2d": np.full((2, 3, 24, 3), 0.5), "joints3d": np.full((2, 3, 24, 4), 0.5),
            "valid": np.ones((2, 3), bool), "K": K}
    with pytest.raises(InputError, match=f"^fit_bodies.{argument}: "):
        fit_bodies(body=body, **change(good))


def test_accuracy_on_a_synthetic_scene(scene, fitted, body):
    keypoints, _, truth = scene
    joints = _joints(body, fitted)
    mpjpe = np.linalg.norm(joints - truth, axis=-1).mean()
    aligned = umeyama(joints, truth).apply(torch.as_tensor(joints)).numpy()
    pa_mpjpe = np.linalg.norm(aligned - truth, axis=-1).mean()
    depth_error = np.abs(joints[..., 0, 2] / truth[..., 0, 2] - 1)
    print(f"MPJPE {1e3 * mpjpe:.1f} mm, PA-MPJPE {1e3 * pa_mpjpe:.1f} mm, depth error mean "
          f"{100 * depth_error.mean():.2f}% max {100 * depth_error.max():.2f}%, reprojection "
          f"{fitted.reprojection_px.mean():.2f} px (noise {MEAN_NOISE_PX:.2f} px)")
    assert mpjpe < 0.060 and pa_mpjpe < 0.040
    assert depth_error.max() < 0.05
    assert 0.6 * MEAN_NOISE_PX < fitted.reprojection_px.mean() < 1.3 * MEAN_NOISE_PX


def test_mis_detected_keypoints_barely_move_the_fit(scene, body):
    keypoints, joints3d, truth = scene
    rng = np.random.default_rng(5)
    wrong = rng.random(keypoints.shape[:-1]) < 0.05
    outliers = keypoints.copy()
    outliers[..., :2] += wrong[..., None] * rng.uniform(-150, 150, keypoints.shape[:-1] + (2,))
    fit = fit_bodies(outliers, joints3d, np.ones(keypoints.shape[:2], bool), K, body)
    assert np.linalg.norm(_joints(body, fit) - truth, axis=-1).mean() < 0.060


def test_2d_keypoints_alone_converge(scene, body):
    keypoints, joints3d, _ = scene
    fit = fit_bodies(keypoints, joints3d * [1, 1, 1, 0], np.ones(keypoints.shape[:2], bool), K, body)
    print(f"2D only: reprojection {fit.reprojection_px.mean():.2f} px (noise {MEAN_NOISE_PX:.2f} px)")
    assert fit.reprojection_px.mean() < 1.5 * MEAN_NOISE_PX and fit.reprojection_px.max() < 4 * MEAN_NOISE_PX


def test_initialisation_is_in_the_basin(scene, body):
    keypoints, joints3d, truth = scene
    start = fit_bodies(keypoints, joints3d, np.ones(keypoints.shape[:2], bool), K, body, BodyFitConfig(iterations=0))
    joints = _joints(body, start)
    aligned = umeyama(joints, truth).apply(torch.as_tensor(joints)).numpy()
    assert np.linalg.norm(aligned - truth, axis=-1).mean() < 0.05          # every yaw, facing away included
    depth_error = np.abs(joints[..., 0, 2] / truth[..., 0, 2] - 1)
    assert depth_error.mean() < 0.03 and depth_error.max() < 0.10


def test_two_calls_are_bitwise_identical(body):
    keypoints, joints3d, _ = _scene(body, people=2, frames=10, seed=3)
    valid = np.ones((2, 10), bool)
    first, second = (fit_bodies(keypoints, joints3d, valid, K, body, BodyFitConfig(iterations=30)) for _ in range(2))
    for field in dataclasses.fields(first):
        np.testing.assert_array_equal(getattr(first, field.name), getattr(second, field.name))


def test_smoothness_lowers_the_acceleration(body):
    keypoints, joints3d, truth = _scene(body, people=2, frames=30, seed=4, noise_px=4.0)
    valid = np.ones((2, 30), bool)
    smooth, rough = (_joints(body, fit_bodies(keypoints, joints3d, valid, K, body, BodyFitConfig(w_smooth=w)))
                     for w in (BodyFitConfig().w_smooth, 0.0))
    assert _acceleration(smooth) < 0.5 * _acceleration(rough)
    assert np.linalg.norm(smooth - truth, axis=-1).mean() < np.linalg.norm(rough - truth, axis=-1).mean()
