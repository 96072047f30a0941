import numpy as np
import pytest

from multithumbs.perception.camera import (
    cam_crop_to_full,
    hmr2_focal_length,
    hmr2_intrinsics,
    phalp_joints_to_pixels,
    pixels_to_phalp_joints,
)


def test_intrinsics_hand_computed():
    # 640x360: S = 640, f = 5000 / 256 * 640 = 12500; PHALP pads 140 rows on top.
    K = hmr2_intrinsics((360, 640))
    assert hmr2_focal_length((360, 640)) == pytest.approx(12500.0)
    np.testing.assert_allclose(K, [[12500, 0, 319.5], [0, 12500, 179.5], [0, 0, 1]])
    # Odd padding: 361 rows pad 139 on top, so the square's centre is 180.5 rows into the frame, minus 0.5.
    assert hmr2_intrinsics((361, 640))[1, 2] == pytest.approx(180.5)
    assert hmr2_intrinsics((361, 640), padded_square=False)[1, 2] == pytest.approx(180.0)


def test_phalp_camera_matches_phalps_own_projection():
    # PHALP projects its 'camera' translation with focal 5000 on the 256-px padded square; our K must agree.
    h, w = 360, 640
    point = np.array([0.1, -0.2, 25.0])
    u_res = 5000 * point[:2] / point[2] + 128                      # PHALP, 256-px square, continuous
    side, top = 640, (640 - 360) // 2
    u_cont = u_res * side / 256 - np.array([0, top])               # full frame, continuous pixels
    uvw = hmr2_intrinsics((h, w)) @ point
    np.testing.assert_allclose(uvw[:2] / uvw[2], u_cont - 0.5)     # ours: pixel centres at integers
    np.testing.assert_allclose(uvw[:2] / uvw[2], [369.5, 79.5])    # by hand: 12500*0.004+319.5, -100+179.5


def test_cam_crop_to_full_hand_computed():
    # s=0.8, tx=0.05, ty=-0.1, box centre (400, 200), side 200, image 640x360, f=12500:
    # b*s = 160, tz = 25000/160 = 156.25, tx' = 2*80/160 + 0.05 = 1.05, ty' = 2*20/160 - 0.1 = 0.15
    t = cam_crop_to_full(np.array([0.8, 0.05, -0.1]), np.array([400.0, 200.0]), np.array(200.0), (360, 640), 12500.0)
    np.testing.assert_allclose(t, [1.05, 0.15, 156.25])


def test_cam_crop_to_full_centres_the_body_on_the_box():
    # With no crop offset, the body origin projects to the box centre; batch-agnostic shapes.
    centres = np.array([[[100.0, 50.0], [500.0, 300.0]]])
    t = cam_crop_to_full(np.array([[[0.5, 0, 0], [1.2, 0, 0]]]), centres, np.array([[120.0, 80.0]]), (360, 640),
                         12500.0)
    assert t.shape == (1, 2, 3)
    K = hmr2_intrinsics((360, 640), padded_square=False)
    uv = np.einsum("ij,...j->...i", K, t)
    np.testing.assert_allclose(uv[..., :2] / uv[..., 2:], centres - 0.5, atol=1e-6)


def test_phalp_joint_normalisation_round_trip():
    px = np.random.default_rng(0).uniform(0, 300, (3, 45, 2))
    flat = pixels_to_phalp_joints(px, (240, 320))
    assert flat.shape == (3, 90)
    np.testing.assert_allclose(phalp_joints_to_pixels(flat, (240, 320)), px)
