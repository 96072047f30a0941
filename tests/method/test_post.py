import dataclasses

import numpy as np
import pytest

from multithumbs.geometry import intrinsics_from_fov, look_at, project_points
from multithumbs.method.post import PostConfig, PostInput, post_process
from multithumbs.metrics.gt_free import jitter
from multithumbs.synth.motion import BODY_TO_WORLD
from scipy.spatial.transform import Rotation

FAST = PostConfig(iterations=150)


def _static_person(body, frames=30):
    orient = np.tile(Rotation.from_matrix(BODY_TO_WORLD).as_rotvec(), (1, frames, 1))
    pose = np.zeros((1, frames, 23, 3))
    pose[..., 15, 2], pose[..., 16, 2] = -1.2, 1.2  # arms down
    betas = np.zeros((1, 10))
    transl = np.tile([0.5, 0.2, 0.95], (1, frames, 1))
    K = intrinsics_from_fov(640, 360, 60)
    R, t = look_at(np.array([3.5, 0.0, 1.6]), np.array([0.5, 0.2, 0.9]))
    joints = body.joints(orient, pose, betas, transl).double().numpy()
    uv = project_points(joints, K, R, t)
    keypoints = np.concatenate([uv, np.ones(uv.shape[:-1] + (1,))], axis=-1)
    return PostInput(orient, pose, betas, transl, np.ones((1, frames), bool), keypoints,
                     np.tile(K, (frames, 1, 1)), np.tile(R, (frames, 1, 1)), np.tile(t, (frames, 1)),
                     np.zeros(0, np.int64), np.zeros((1, 0), bool), (360, 640)), joints


def test_post_processing_keeps_a_static_pose_still(body):
    data, joints = _static_person(body)
    out = post_process(data, body, FAST)
    after = body.joints(out.global_orient, out.body_pose, out.betas, out.transl).double().numpy()
    assert np.abs(after - joints).max() < 2e-3


def test_post_processing_lowers_jitter(body):
    data, joints = _static_person(body)
    rng = np.random.default_rng(0)
    noisy = dataclasses.replace(data, transl=data.transl + rng.normal(0, 0.02, data.transl.shape),
                                body_pose=data.body_pose + rng.normal(0, 0.05, data.body_pose.shape))
    before = body.joints(noisy.global_orient, noisy.body_pose, noisy.betas, noisy.transl).double().numpy()
    out = post_process(noisy, body, FAST)
    after = body.joints(out.global_orient, out.body_pose, out.betas, out.transl).double().numpy()
    valid = np.ones((1, 30), bool)
    assert jitter(after, valid, 30.0).mean() < 0.3 * jitter(before, valid, 30.0).mean()
    assert np.linalg.norm(after - joints, axis=-1).mean() < np.linalg.norm(before - joints, axis=-1).mean()
    assert out.losses[-1] < out.losses[0]


def test_vposer_prior_needs_a_model(body):
    data, _ = _static_person(body, frames=4)
    with pytest.raises(ValueError, match="VPoser"):
        post_process(data, body, PostConfig(pose_prior="vposer"))
