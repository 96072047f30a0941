from types import SimpleNamespace

import numpy as np
import pytest
import torch

from multithumbs.errors import InputError
from multithumbs.geometry import intrinsics_from_fov, look_at
from multithumbs.scene import focal as F
from multithumbs.scene import focal_heights

W, H = 640, 360


def _room_points(rng, n=4000):
    P = np.c_[rng.uniform(-4.5, 4.5, n), rng.uniform(-4, 4, n), rng.uniform(0, 3, n)]
    face = rng.integers(0, 3, n)
    P[face == 0, 2] = 0.0
    P[face == 1, 0] = -4.5
    P[face == 2, 1] = np.sign(P[face == 2, 1]) * 4.0
    return P


def _keyframe_tracks(rng, K, eye, target, noise, count=150):
    R, t = look_at(eye, target)
    cam = np.einsum("vij,nj->vni", R, _room_points(rng)) + t[:, None]
    uv = cam[..., :2] / cam[..., 2:] * K[0, 0] + K[:2, 2]
    seen = (cam[..., 2] > 0.3).all(0) & ((uv >= 0) & (uv < [W, H])).all(axis=(0, 2))
    xy = uv[:, seen][:, :count]
    return xy + rng.normal(0, noise, xy.shape)


def test_moving_camera_focal_from_the_bundle_profile():
    rng = np.random.default_rng(0)
    K = intrinsics_from_fov(W, H, 40.0)
    s = np.linspace(0, 1, 8)[:, None]
    xy = _keyframe_tracks(rng, K, np.c_[3.0 - 0.8 * s, -0.6 * s, 1.6 + 0.4 * s], np.c_[-0.8 * s, 1.0 * s, 0.9 + 0.3 * s],
                          noise=0.1)
    focals = np.geomspace(F.focal_from_fov(W, 70), F.focal_from_fov(W, 20), 10)
    rms = F.bundle_profile(xy, (H, W), focals)
    f, rise = F.profile_minimum(focals, rms, 0.05)
    assert f is not None and abs(f / K[0, 0] - 1) < 0.05, (f, K[0, 0], rise)
    # A flat profile (nothing pins the focal length down) gives nothing.
    assert F.profile_minimum(focals, 0.2 + 1e-4 * np.abs(np.arange(10) - 5), 0.05)[0] is None


def test_rotating_camera_focal_from_a_homography():
    rng = np.random.default_rng(1)
    K = intrinsics_from_fov(W, H, 55.0)
    rays = np.c_[rng.uniform(-0.5, 0.5, (200, 2)), np.ones(200)]
    from scipy.spatial.transform import Rotation

    R = Rotation.from_euler("yx", [8.0, 3.0], degrees=True).as_matrix()
    project = lambda d: (d @ K.T)[:, :2] / (d @ K.T)[:, 2:]
    f, angle = F.focal_from_rotation(project(rays), project(rays @ R.T), (H, W))
    assert abs(f / K[0, 0] - 1) < 0.01 and 8 < angle < 9.5


def test_static_camera_falls_through_to_the_default():
    rng = np.random.default_rng(2)
    frame = np.repeat(rng.integers(0, 256, (H // 8, W // 8, 3)).astype(np.uint8), 8, 0).repeat(8, 1)
    frames = np.repeat(frame[None], 10, axis=0)
    estimate, why = F.focal_from_motion(frames)
    assert estimate is None and why == "static camera"
    chosen = F.estimate_focal(frames, [(0, 5), (5, 10)])
    assert chosen.source == "default" and chosen.focal_px == pytest.approx(F.focal_from_fov(W, 60.0))
    assert "static camera (2 shots)" in chosen.detail
    assert chosen.line().startswith("focal length 554 px (default 60° guess, lines: ")


def _pole_tracks(rng, K, pitch_deg=15.0, height=2.4, depth=(2.0, 9.0), people=4, frames=30, noise=1.0):
    """People as 1.45 m poles (mid-ankle to mid-shoulder) walking on the floor, seen by a pitched camera."""
    R = focal_heights._camera_rotation(np.deg2rad(pitch_deg), np.deg2rad(2.0))
    C = np.array([0.0, 0.0, height])
    kp = np.zeros((people, frames, 24, 3))
    start = np.c_[rng.uniform(-1.5, 1.5, people), rng.uniform(*depth, people)]
    walk = rng.normal(0, 0.05, (people, frames, 2)).cumsum(axis=1)
    ground = start[:, None] + walk
    for z, joints in ((0.08, focal_heights.FOOT_JOINTS), (1.53, focal_heights.TOP_JOINTS)):
        X = np.concatenate([ground, np.full((people, frames, 1), z)], axis=2)
        cam = (X - C) @ R.T
        uv = cam[..., :2] / cam[..., 2:] * K[0, 0] + K[:2, 2]
        for j in joints:
            kp[:, :, j, :2] = uv + rng.normal(0, noise, uv.shape)
            kp[:, :, j, 2] = 0.9
    return [SimpleNamespace(keypoints2d=kp, valid=np.ones((people, frames), bool))]


def test_heights_give_the_focal_length_of_a_known_camera():
    rng = np.random.default_rng(3)
    for fov in (40.0, 70.0):
        K = intrinsics_from_fov(W, H, fov)
        estimate, why = focal_heights.focal_from_heights(_pole_tracks(rng, K), (H, W))
        assert estimate is not None and estimate.source == "heights", why
        assert abs(estimate.focal_px / K[0, 0] - 1) < 0.05, (fov, estimate)
    # Everybody at one depth: nothing to go on; the chain says so and takes the default.
    flat = _pole_tracks(rng, K, depth=(5.0, 5.0), people=1, frames=60, noise=0.0)
    flat[0].keypoints2d[:, :, :, 1] = flat[0].keypoints2d[:, :1, :, 1]
    estimate, why = focal_heights.focal_from_heights(flat, (H, W))
    assert estimate is None and "one depth" in why
    frames = np.zeros((4, H, W, 3), np.uint8)
    chosen = F.estimate_focal(frames, [(0, 4)], tracks=flat)
    assert chosen.source == "default" and "heights: people at one depth" in chosen.detail


def test_learned_model_intrinsics():
    from multithumbs.scene.learned import LearnedSpaceConfig, vggt_shared_space

    def fake_vggt(images):  # VGGT's documented output: fov_h 1.0, fov_w 1.4 radians
        s, _, h, w = images.shape
        enc = torch.tensor([[0, 0, 0, 0, 0, 0, 1, 1.0, 1.4]] * s, dtype=torch.float32)[None]
        return {"pose_enc": enc, "depth": torch.ones(1, s, h, w, 1), "depth_conf": torch.full((1, s, h, w), 2.0)}

    frames = np.random.default_rng(4).integers(0, 256, (6, 90, 160, 3)).astype(np.uint8)
    learned = lambda a, b: vggt_shared_space(fake_vggt, a, b, 0, LearnedSpaceConfig(stride=4))
    chosen = F.estimate_focal(frames, [(0, 6)], learned=learned)
    fx = 259 / np.tan(0.7) * 160 / 518
    fy = 147 / np.tan(0.5) * 90 / 294
    assert chosen.source == "learned" and chosen.detail == "vggt"
    assert chosen.focal_px == pytest.approx(np.sqrt(fx * fy), rel=1e-5)


def test_bad_input_is_one_line():
    for call in (lambda: F.focal_from_motion(np.zeros((5, 10, 10))),
                 lambda: F.estimate_focal(np.zeros((5, 10, 10, 3)), [(0, 5)]),
                 lambda: F.bundle_profile(np.zeros((2, 20, 2)), (H, W), [500.0]),
                 lambda: focal_heights.pole_observations([SimpleNamespace(keypoints2d=np.zeros((1, 3, 17, 3)),
                                                              valid=np.ones((1, 3), bool))])):
        with pytest.raises(InputError) as info:
            call()
        assert "\n" not in str(info.value)


def test_a_moving_shot_without_enough_room_tracks_falls_through(monkeypatch):
    # A shot that is not static but whose first frame holds fewer room tracks than needed (Megamind's
    # close-ups: the camera drifts, the room is hidden by faces) once crashed on an empty selection.
    from multithumbs.scene import tracking

    monkeypatch.setattr(tracking, "is_static", lambda *args, **kwargs: False)
    rng = np.random.default_rng(0)
    frames = rng.integers(0, 255, (12, 72, 96, 3), dtype=np.uint8)
    few = F.FocalConfig(min_tracks=10**6)
    estimate, why = F.focal_from_motion(frames, config=few)
    assert estimate is None and "room tracks" in why
    chosen = F.estimate_focal(frames, [(0, 12)], config=few)
    assert chosen.source == "default" and "moving camera" in chosen.detail
