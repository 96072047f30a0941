import numpy as np
import pytest
import torch

from multithumbs import geometry as g


@pytest.fixture
def rng():
    return np.random.default_rng(0)


def test_axis_angle_round_trip_batch_shapes(rng):
    rotvec = rng.normal(size=(4, 5, 3))
    R = g.axis_angle_to_matrix(rotvec)
    assert R.shape == (4, 5, 3, 3)
    np.testing.assert_allclose(R @ np.swapaxes(R, -1, -2), np.broadcast_to(np.eye(3), R.shape), atol=1e-12)
    back = g.matrix_to_axis_angle(R)
    np.testing.assert_allclose(g.axis_angle_to_matrix(back), R, atol=1e-10)


def test_rotation_6d_round_trip_and_gradcheck():
    R = g.axis_angle_to_matrix(torch.randn(7, 3, dtype=torch.float64))
    torch.testing.assert_close(g.rotation_6d_to_matrix(g.matrix_to_rotation_6d(R)), R)
    d6 = torch.randn(2, 6, dtype=torch.float64, requires_grad=True)
    assert torch.autograd.gradcheck(g.rotation_6d_to_matrix, (d6,))


def test_camera_centre_and_look_at(rng):
    eye, target = np.array([3.0, -1.0, 1.6]), np.array([0.0, 0.5, 0.9])
    R, t = g.look_at(eye, target)
    np.testing.assert_allclose(g.camera_centre(R, t), eye, atol=1e-12)
    # The target lies on the optical axis in front of the camera; world up points up in the image (-y).
    cam = g.world_to_camera(target[None], R, t)[0]
    np.testing.assert_allclose(cam[:2], 0, atol=1e-12)
    assert cam[2] > 0
    up_cam = R @ np.array([0, 0, 1.0])
    assert up_cam[1] < 0
    np.testing.assert_allclose(np.linalg.det(R), 1.0)


def test_projection_unprojection_round_trip(rng):
    K = g.intrinsics_from_fov(640, 360, 60)
    pts = rng.uniform([-1, -1, 2], [1, 1, 6], size=(50, 3))
    uv = g.project(pts, K)
    back = g.unproject(uv, pts[:, 2], K)
    np.testing.assert_allclose(back, pts, atol=1e-10)
    # principal point: the optical axis lands on the image centre
    np.testing.assert_allclose(g.project(np.array([[0, 0, 3.0]]), K), [[319.5, 179.5]])


def test_reexpress_for_intrinsics_keeps_pixels_and_projected_size(rng):
    K_true = g.intrinsics_from_fov(640, 360, 60)
    K_hmr = g.intrinsics(5000 / 256 * 640, 5000 / 256 * 640, 320.0, 180.0)  # HMR2's assumed camera
    pts = rng.uniform([-1, -1, 2], [1, 1, 6], size=(4, 7, 3))  # (people, joints, 3)
    moved = g.reexpress_for_intrinsics(pts, K_true, K_hmr)
    assert moved.shape == pts.shape
    np.testing.assert_allclose(g.project(moved, K_hmr), g.project(pts, K_true), atol=1e-8)
    np.testing.assert_allclose(moved[..., 2] / pts[..., 2], K_hmr[0, 0] / K_true[0, 0], rtol=1e-12)
    np.testing.assert_allclose(g.reexpress_for_intrinsics(moved, K_hmr, K_true), pts, atol=1e-10)
    np.testing.assert_allclose(g.reexpress_for_intrinsics(pts, K_true, K_true), pts, atol=1e-12)
    # per-frame intrinsics broadcast over the leading axis
    per_frame = g.reexpress_for_intrinsics(pts, np.stack([K_true] * 4), np.stack([K_hmr] * 4))
    np.testing.assert_allclose(per_frame, moved, atol=1e-10)


def test_umeyama_recovers_similarity_and_matches_closed_form(rng):
    x = rng.normal(size=(3, 40, 3))
    R = g.axis_angle_to_matrix(rng.normal(size=(3, 3)))
    s, t = rng.uniform(0.5, 2.0, 3), rng.normal(size=(3, 3))
    y = s[:, None, None] * x @ np.swapaxes(R, -1, -2) + t[:, None]
    sim = g.umeyama(x, y + 1e-3 * rng.normal(size=y.shape))
    s_est, R_est, t_est = sim.numpy()
    np.testing.assert_allclose(s_est, s, rtol=1e-3)
    np.testing.assert_allclose(R_est, R, atol=1e-3)
    # Closed form s = tr(DS) / var(x) (Umeyama 1991, eq. 42) on a noisy case.
    x0, y0 = x[0], y[0] + 0.05 * rng.normal(size=y[0].shape)
    xc, yc = x0 - x0.mean(0), y0 - y0.mean(0)
    U, D, Vt = np.linalg.svd(yc.T @ xc / len(xc))
    S = np.diag([1, 1, np.sign(np.linalg.det(U) * np.linalg.det(Vt))])
    s_closed = np.trace(np.diag(D) @ S) / (xc ** 2).sum(1).mean()
    np.testing.assert_allclose(g.umeyama(x0, y0).numpy()[0], s_closed, rtol=1e-9)


def test_umeyama_fixes_reflections(rng):
    x = rng.normal(size=(30, 3))
    y = x * np.array([1, 1, -1])  # a mirror image: the best rotation must still have det +1
    R = g.umeyama(x, y).numpy()[1]
    np.testing.assert_allclose(np.linalg.det(R), 1.0)


def test_similarity_inverse_compose(rng):
    a = g.Similarity.from_numpy(1.3, g.axis_angle_to_matrix(rng.normal(size=3)), rng.normal(size=3))
    b = g.Similarity.from_numpy(0.7, g.axis_angle_to_matrix(rng.normal(size=3)), rng.normal(size=3))
    p = torch.from_numpy(rng.normal(size=(10, 3)))
    torch.testing.assert_close(a.compose(b).apply(p), a.apply(b.apply(p)))
    torch.testing.assert_close(a.inverse().apply(a.apply(p)), p)


def test_transform_cameras_keeps_projections(rng):
    K = g.intrinsics_from_fov(640, 360, 60)
    R, t = g.look_at(np.array([3.0, 0, 1.5]), np.zeros(3))
    pts = rng.uniform(-0.5, 0.5, size=(20, 3))
    sim = g.Similarity.from_numpy(2.5, g.axis_angle_to_matrix(rng.normal(size=3)), rng.normal(size=3))
    R2, t2 = g.transform_cameras(sim, torch.from_numpy(R), torch.from_numpy(t))
    moved = sim.apply(torch.from_numpy(pts))
    np.testing.assert_allclose(g.project_points(moved, torch.from_numpy(K), R2, t2).numpy(),
                               g.project_points(pts, K, R, t), atol=1e-9)
    # camera centres move like points
    np.testing.assert_allclose(g.camera_centre(R2, t2).numpy(),
                               sim.apply(torch.from_numpy(g.camera_centre(R, t))[None])[0].numpy(), atol=1e-12)
