"""The focal length from straight edges (vanishing points of three orthogonal directions)."""

import cv2
import numpy as np
import pytest

from multithumbs.errors import InputError
from multithumbs.geometry import intrinsics_from_fov
from multithumbs.scene import focal as F
from multithumbs.scene import focal_lines as L

W, H = 640, 360


def _camera(yaw_deg: float, pitch_deg: float) -> np.ndarray:
    """World-to-camera rotation (world z up, camera looking along world +y turned by yaw, pitched down)."""
    from scipy.spatial.transform import Rotation

    base = np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]])  # level, looking along +y
    turn = Rotation.from_euler("ZX", [yaw_deg, -pitch_deg], degrees=True).as_matrix()
    return base @ turn.T


def _room_picture(K, R, eye, rng, edges=160, clutter=40) -> np.ndarray:
    """A grey ``(H, W, 3)`` frame with the edges of a 9 x 8 x 3 m box room drawn in it: axis-aligned
    segments on the floor and walls (planks, frames, corners), plus ``clutter`` segments at random angles."""
    img = np.full((H, W, 3), 200, np.uint8)

    def draw(P, Q, shade):
        cam = (np.stack([P, Q]) - eye) @ R.T
        if (cam[:, 2] < 0.2).any():
            return
        uv = cam[:, :2] / cam[:, 2:] * K[0, 0] + K[:2, 2]
        cv2.line(img, tuple(np.round(uv[0] * 16).astype(int)), tuple(np.round(uv[1] * 16).astype(int)),
                 (shade,) * 3, 2, cv2.LINE_AA, shift=4)

    for _ in range(edges):
        axis = rng.integers(0, 3)
        P = np.array([rng.uniform(-4.5, 4.5), rng.uniform(-4, 4), rng.uniform(0, 3)])
        face = rng.integers(0, 2)  # on the floor or on the far wall
        if face == 0:
            P[2] = 0.0
            axis = rng.integers(0, 2)
        else:
            P[1] = 4.0
            axis = (0, 2)[rng.integers(0, 2)]
        Q = P.copy()
        Q[axis] += rng.uniform(0.8, 2.5) * (1 if rng.random() < 0.5 else -1)
        draw(P, Q, int(rng.integers(0, 90)))
    for _ in range(clutter):
        P = rng.uniform([-3, -2, 0], [3, 3, 2.5])
        draw(P, P + rng.normal(0, 0.7, 3), int(rng.integers(0, 90)))
    return img


@pytest.mark.parametrize("fov, yaw, pitch", [(40.0, 25.0, 12.0), (70.0, -35.0, 8.0), (55.0, 10.0, 20.0)])
def test_the_focal_length_of_a_drawn_room(fov, yaw, pitch):
    rng = np.random.default_rng(int(fov))
    K = intrinsics_from_fov(W, H, fov)
    eye = np.array([0.3, -3.5, 1.6])
    frames = np.stack([_room_picture(K, _camera(yaw + 2 * k, pitch), eye, rng) for k in range(4)])
    estimate, why = L.focal_from_lines(frames, [(0, 4)], F.FocalConfig(line_frames=4))
    assert estimate is not None and estimate.source == "lines", why
    assert abs(estimate.focal_px / K[0, 0] - 1) < 0.02, (fov, estimate)
    assert estimate.line().startswith(f"focal length {estimate.focal_px:.0f} px (vanishing points, 4 of 4 frames")


def test_one_frames_rotation_and_focal_length():
    rng = np.random.default_rng(5)
    K = intrinsics_from_fov(W, H, 50.0)
    R = _camera(30.0, 15.0)
    gray = cv2.cvtColor(_room_picture(K, R, np.array([0.0, -3.0, 1.5]), rng, edges=200), cv2.COLOR_RGB2GRAY)
    seg = L.line_segments(gray, 20.0, 300)
    assert seg.shape[1] == 4 and 50 < len(seg) <= 300
    found = L.frame_focal(seg, (H, W), np.geomspace(200, 2000, 16))
    assert found is not None and abs(found.focal_px / K[0, 0] - 1) < 0.02 and found.log_std < 0.03
    # Its three directions are the room's axes (up to order and sign): |R_found^T R e_k| is a permutation.
    overlap = np.abs(found.rotation.T @ R)
    np.testing.assert_allclose(np.sort(overlap.max(axis=1)), 1.0, atol=0.01)


def test_a_level_camera_square_to_the_wall_pins_nothing_down():
    # Looking along a room axis, level: the forward vanishing point sits at the centre, the other two at
    # infinity, and every focal length explains the edges equally well.
    rng = np.random.default_rng(6)
    K = intrinsics_from_fov(W, H, 50.0)
    frames = np.stack([_room_picture(K, _camera(0.0, 0.0), np.array([0.2 * k, -3.5, 1.5]), rng) for k in range(4)])
    estimate, why = L.focal_from_lines(frames, [(0, 4)], F.FocalConfig(line_frames=4))
    assert estimate is None and "pin it down" in why
    chosen = F.estimate_focal(frames, [(0, 4)])
    assert chosen.source == "default" and "lines: " in chosen.detail


def test_opencv_sample_photos_against_opencvs_own_calibration(opencv_samples):
    """OpenCV's chessboard photos ``left01..14.jpg`` with the calibration OpenCV ships beside them
    (``left_intrinsics.yml``, written by ``samples/cpp/calibration.cpp``): undistorted to a centred principal
    point, the two board directions' vanishing points give the focal length of that calibration."""
    store = cv2.FileStorage(str(opencv_samples / "left_intrinsics.yml"), cv2.FILE_STORAGE_READ)
    K, dist = store.getNode("camera_matrix").mat(), store.getNode("distortion_coefficients").mat()
    paths = sorted(opencv_samples.glob("left[0-9][0-9].jpg"))
    assert len(paths) >= 10
    frames = []
    for path in paths:
        image = cv2.cvtColor(cv2.imread(str(path)), cv2.COLOR_BGR2RGB)
        h, w = image.shape[:2]
        centred = K.copy()
        centred[0, 2], centred[1, 2] = (w - 1) / 2, (h - 1) / 2
        frames.append(cv2.undistort(image, K, dist, None, centred))
    ranges = [(i, i + 1) for i in range(len(frames))]
    estimate, why = L.focal_from_lines(np.stack(frames), ranges, F.FocalConfig(line_frames=1))
    assert estimate is not None, why
    assert abs(estimate.focal_px / K[0, 0] - 1) < 0.03, (estimate, K[0, 0])


def test_bad_input_is_one_line():
    for call in (lambda: L.focal_from_lines(np.zeros((3, 10, 10)), [(0, 3)]),
                 lambda: L.line_segments(np.zeros((10, 10, 3), np.uint8), 20.0, 10)):
        with pytest.raises(InputError) as info:
            call()
        assert "\n" not in str(info.value)
