import cv2
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from multithumbs.datasets.cameras import Camera, metric_extrinsics
from multithumbs.errors import InputError

K = np.array([[40.0, 0, 32.0], [0, 41.0, 24.0], [0, 0, 1]])
R = Rotation.from_euler("xyz", [10, -20, 5], degrees=True).as_matrix()
t = np.array([0.1, -0.2, 3.0])


def points(n=50, seed=0):
    rng = np.random.default_rng(seed)
    cam = np.column_stack([rng.uniform(-1, 1, n), rng.uniform(-0.7, 0.7, n), rng.uniform(2, 4, n)])
    return (cam - t) @ R  # world points in front of the camera


def test_fisheye_projection_is_opencv_fisheye():
    D = np.array([0.05, 0.01, -0.002, 0.0005])
    cam = Camera("cam01", K, D, "fisheye", R, t, (48, 64))
    X = points()
    expected, _ = cv2.fisheye.projectPoints(X[:, None], cv2.Rodrigues(R)[0], t, K, D)
    np.testing.assert_allclose(cam.project(X), expected.reshape(-1, 2), atol=1e-9)
    assert cam.project(X.reshape(5, 10, 3)).shape == (5, 10, 2)


def test_zero_fisheye_coefficients_are_equidistant_not_pinhole():
    cam = Camera("cam01", K, np.zeros(4), "fisheye", np.eye(3), np.zeros(3), (48, 64))
    X = np.array([[1.0, 0.0, 1.0]])  # 45 degrees off axis
    u = cam.project(X)[0, 0]
    assert u == pytest.approx(32.0 + 40.0 * np.pi / 4)
    assert cam.project_undistorted(X)[0, 0] == pytest.approx(32.0 + 40.0)


@pytest.mark.parametrize("model,D", [("fisheye", [0.05, 0.01, 0.0, 0.0]), ("radial", [0.05, -0.02, 0.001, 0.002, 0.0])])
def test_undistorting_a_projection_gives_the_pinhole_projection(model, D):
    cam = Camera("c", K, np.array(D), model, R, t, (48, 64))
    X = points()
    np.testing.assert_allclose(cam.undistort_points(cam.project(X)), cam.project_undistorted(X), atol=1e-4)


def test_radial_projection_is_opencv():
    D = np.array([0.05, -0.02, 0.001, 0.002, 0.0])
    cam = Camera("master", K, D, "radial", R, t, (48, 64))
    X = points()
    expected, _ = cv2.projectPoints(X, cv2.Rodrigues(R)[0], t, K, D)
    np.testing.assert_allclose(cam.project(X), expected.reshape(-1, 2), atol=1e-9)
    np.testing.assert_allclose(cam.centre, -R.T @ t)


def test_metric_extrinsics_removes_the_alignment_scale():
    E = np.eye(4)
    E[:3, :3], E[:3, 3] = R, t
    S = np.diag([2.0, 2.0, 2.0, 1.0])  # world -> a world twice as large
    S[:3, 3] = [0.3, 0.1, -0.2]
    colmap = np.eye(4)
    colmap[:3, :3] = R
    colmap[:3, 3] = 2 * t - R @ S[:3, 3]  # the same camera seen in the scaled world
    R_m, t_m, s = metric_extrinsics(colmap @ S)
    assert s == pytest.approx(2.0)
    np.testing.assert_allclose(R_m, R, atol=1e-12)
    np.testing.assert_allclose(t_m, t, atol=1e-12)


@pytest.mark.parametrize("matrix,needle", [
    (np.zeros((3, 4)), "determinant"),
    (np.diag([1.0, 2.0, 1.0, 1.0]), "scaled rotation"),
    (np.eye(5), "3x4 or 4x4"),
])
def test_metric_extrinsics_rejects_non_similarities(matrix, needle):
    with pytest.raises(InputError, match=needle):
        metric_extrinsics(matrix, "cam")


@pytest.mark.parametrize("kwargs,needle", [
    (dict(distortion=np.zeros(3), model="fisheye"), "4 coefficients"),
    (dict(distortion=np.zeros(3), model="radial"), "distortion coefficients"),
    (dict(model="spherical"), "unknown lens model"),
    (dict(R=2 * np.eye(3)), "not a rotation"),
    (dict(K=np.eye(2)), "K must be"),
])
def test_camera_rejects_bad_calibration(kwargs, needle):
    args = dict(name="c", K=K, distortion=np.zeros(0), model="pinhole", R=np.eye(3), t=np.zeros(3), image_size=(4, 4))
    args.update(kwargs)
    with pytest.raises(InputError, match=needle):
        Camera(**args)
