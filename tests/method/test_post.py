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


def _reference_loss(data, config, joints, body_pose, betas, transl):
    """The objective of the module docstring written plainly, as the loop computed it before it was
    restructured for speed: :class:`multithumbs.method.post._Terms` must give the same value and gradients."""
    import torch

    from multithumbs.geometry import project, world_to_camera
    from multithumbs.method.post import _windows
    as_t = lambda a: torch.as_tensor(np.asarray(a), dtype=torch.float64)  # noqa: E731
    valid = torch.as_tensor(data.valid)
    windows = torch.as_tensor(_windows(data.valid, data.cut_frames, data.matched_at_cut, config.smooth_order))
    norm = 0.5 * max(data.image_size)
    K, R, t, kp = as_t(data.K), as_t(data.R), as_t(data.t), as_t(data.keypoints)
    kp_w = torch.where(kp[..., 2] >= config.keypoint_confidence, kp[..., 2], 0.0) * valid[..., None]
    vmask = valid.double()
    diff = joints[:, 1:] - joints[:, :-1]
    if config.smooth_order == 2:
        diff = diff[:, 1:] - diff[:, :-1]
    smooth = (diff.pow(2).sum(-1).mean(-1) * windows).sum() / windows.sum().clamp(min=1)
    pose_dev = ((body_pose - as_t(data.body_pose)).pow(2).sum((-1, -2)) * vmask).sum() / vmask.sum()
    prior = config.w_shape * betas.pow(2).sum(-1).mean() + config.w_pose_prior * pose_dev
    sigma2 = (config.robust_sigma_px / norm) ** 2
    rho = (lambda r2: sigma2 * r2 / (r2 + sigma2)) if sigma2 > 0 else (lambda r2: r2)  # noqa: E731
    uv = project(world_to_camera(joints, R, t), K)
    data2d = (rho(((uv - kp[..., :2]) / norm).pow(2).sum(-1)) * kp_w).sum() / kp_w.sum()
    root = ((transl - as_t(data.transl)).pow(2).sum(-1) * vmask).sum() / vmask.sum()
    loss = config.w_smooth * (smooth + prior) + config.w_2d * data2d + config.w_root * root
    terms = []
    for p in range(data.valid.shape[0]):
        for i, c in enumerate(data.cut_frames):
            if data.matched_at_cut[p, i] and data.valid[p, c - 1] and data.valid[p, c]:
                for src, dst in ((c - 1, c), (c, c - 1)):
                    uv_x = project(world_to_camera(joints[p, src], R[dst], t[dst]), K[dst])
                    w = kp_w[p, dst]
                    terms.append((rho(((uv_x - kp[p, dst, :, :2]) / norm).pow(2).sum(-1)) * w).sum() / w.sum())
    return loss + config.w_cross * torch.stack(terms).mean()


def test_the_optimised_objective_is_the_documented_one():
    import torch

    from multithumbs.body.model import BodyModel
    from multithumbs.method.post import _Terms
    body = BodyModel(dtype=torch.float64)
    data, _ = _static_person(body, frames=12)
    rng = np.random.default_rng(4)
    # Two people, a cut at frame 6 (person 0 matched across it), gaps, noisy keypoints and poses.
    stack = lambda a: np.concatenate([a, a], axis=0)  # noqa: E731
    valid = np.ones((2, 12), bool)
    valid[1, 9:] = False
    keypoints = stack(data.keypoints) + np.concatenate([rng.normal(0, 3, (2, 12, 24, 2)), np.zeros((2, 12, 24, 1))], -1)
    keypoints[..., 2] = rng.uniform(0.1, 1.0, (2, 12, 24))
    data = dataclasses.replace(data, global_orient=stack(data.global_orient), body_pose=stack(data.body_pose),
                               betas=rng.normal(0, 1, (2, 10)),
                               transl=stack(data.transl) + [[[1.0, 0.0, 0.0]], [[0.0] * 3]],
                               valid=valid, keypoints=keypoints, cut_frames=np.array([6]),
                               matched_at_cut=np.array([[True], [False]]))
    for config in (PostConfig(), PostConfig(smooth_order=1), PostConfig(robust_sigma_px=0.0)):
        terms = _Terms(data, config)
        params = [torch.as_tensor(x).clone() + torch.as_tensor(rng.normal(0, 0.05, np.shape(x)))
                  for x in (data.global_orient, data.body_pose, data.betas, data.transl)]
        params = [x.requires_grad_() for x in params]
        orient, pose, betas, transl = params
        joints = body.joints(orient, pose, betas, transl)
        ours = terms.loss(joints, pose, torch.as_tensor(data.body_pose), betas, transl, torch.as_tensor(data.transl))
        reference = _reference_loss(data, config, joints, pose, betas, transl)
        torch.testing.assert_close(ours, reference, atol=0, rtol=1e-12)
        for a, b in zip(torch.autograd.grad(ours, params, retain_graph=True), torch.autograd.grad(reference, params),
                        strict=True):
            torch.testing.assert_close(a, b, atol=1e-12, rtol=1e-9)
        # post_process's first loss is this objective at the inputs.
        first = post_process(data, body, dataclasses.replace(config, iterations=1)).losses[0]
        start = _reference_loss(data, config, body.joints(*(torch.as_tensor(x) for x in (
            data.global_orient, data.body_pose, data.betas, data.transl))), torch.as_tensor(data.body_pose),
            torch.as_tensor(data.betas), torch.as_tensor(data.transl))
        assert abs(first - float(start)) <= 1e-12 * float(start)


def test_a_frame_whose_keypoints_are_far_off_pulls_the_body_with_bounded_force(body):
    # One frame's keypoints all 80 px to the side (a reading of someone else, or mirrored front to back):
    # with squared residuals it drags that frame's body towards them; Geman-McClure bounds its pull.
    data, joints = _static_person(body)
    keypoints = data.keypoints.copy()
    keypoints[0, 15, :, 0] += 80.0
    data = dataclasses.replace(data, keypoints=keypoints)
    moved = {}
    for sigma in (PostConfig().robust_sigma_px, 0.0):
        out = post_process(data, body, dataclasses.replace(FAST, robust_sigma_px=sigma))
        after = body.joints(out.global_orient, out.body_pose, out.betas, out.transl).double().numpy()
        moved[sigma] = np.linalg.norm(after[0, 15] - joints[0, 15], axis=-1).mean()
    assert moved[PostConfig().robust_sigma_px] < 0.5 * moved[0.0], moved
