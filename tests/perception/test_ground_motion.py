"""The camera's motion read from the floor at a person's feet: the floor's shift on a textured synthetic
frame pair with a person moving the other way, where nothing is known, the metric velocity it gives, and
the backend's facing with a standing person seen from a dolly."""

import cv2
import numpy as np

from multithumbs.perception.facing import FacingConfig
from multithumbs.perception.ground_motion import GroundMotionConfig, ground_flow, static_velocity

H, W = 360, 640
FLOOR_SHIFT = (3, 1)     # pixels (right, down) the floor moves from frame 0 to frame 1
PERSON_SHIFT = (-5, 0)   # and the person


def _texture(seed: int, contrast: float) -> np.ndarray:
    noise = np.random.default_rng(seed).random((H + 40, W + 40)).astype(np.float32)
    blurred = cv2.GaussianBlur(noise, (0, 0), 2.0)
    blurred = (blurred - blurred.mean()) / blurred.std()
    return np.clip(128 + contrast * blurred, 0, 255)


def _scene(floor_contrast: float = 30.0, person: bool = True):
    """Two RGB frames, one person's landmarks (feet on row 250), boxes, bit-packed masks and validity."""
    floor, skin = _texture(0, floor_contrast), _texture(1, 90.0)
    frames, masks = [], []
    for k in range(2):
        dx, dy = FLOOR_SHIFT[0] * k, FLOOR_SHIFT[1] * k
        image = floor[20 - dy:20 - dy + H, 20 - dx:20 - dx + W].copy()
        mask = np.zeros((H, W), bool)
        if person:   # a strongly textured body over most of the band beside its feet, moving the other way
            px = PERSON_SHIFT[0] * k
            mask[100:262, 240 + px:380 + px] = True
            image[mask] = skin[20:20 + H, 20 - px:20 - px + W][mask]
        frames.append(np.repeat(image.astype(np.uint8)[..., None], 3, -1))
        masks.append(np.packbits(mask, axis=-1))
    landmarks = np.zeros((1, 2, 33, 5))
    landmarks[..., 3] = 1.0
    landmarks[..., 27:33, 0] = np.linspace(300, 320, 6)
    landmarks[..., 27:33, 1] = 250.0
    boxes = np.tile([290.0, 100.0, 330.0, 255.0], (1, 2, 1))
    return frames, landmarks, boxes, np.stack(masks)[None], np.ones((1, 2), bool)


def test_the_floors_shift_is_found_and_the_persons_own_motion_left_out():
    frames, landmarks, boxes, masks, valid = _scene()
    flow = ground_flow(frames, landmarks, boxes, masks, valid)
    assert flow.shape == (1, 2, 2)
    np.testing.assert_allclose(flow[0, 0], FLOOR_SHIFT, atol=0.1)
    assert np.isnan(flow[0, 1]).all()   # the last frame has no next one
    # Read without the masks, the person's corners outvote the floor's.
    unmasked = ground_flow(frames, landmarks, boxes, np.zeros_like(masks), valid)
    assert np.linalg.norm(unmasked[0, 0] - FLOOR_SHIFT) > 2.0


def test_nothing_is_known_without_feet_or_without_texture():
    frames, landmarks, boxes, masks, valid = _scene()
    hidden = landmarks.copy()
    hidden[..., 27:33, 3] = 0.2
    assert np.isnan(ground_flow(frames, hidden, boxes, masks, valid)).all()
    assert np.isnan(ground_flow(*_scene(floor_contrast=0.0, person=False))).all()   # a plain floor
    assert np.isnan(ground_flow(frames, landmarks, boxes, masks, ~valid)).all()
    assert np.isnan(ground_flow(frames, landmarks, boxes, masks, valid, GroundMotionConfig(enabled=False))).all()


def test_a_static_points_velocity_is_the_shift_at_the_roots_depth():
    K = np.array([[500.0, 0, 320], [0, 400.0, 180], [0, 0, 1]])
    t = 10
    flow = np.tile([2.0, -1.0], (1, t, 1))
    flow[0, 3] = [8.0, -4.0]                 # one frame's shift, averaged with its neighbours'
    flow[0, 7:] = np.nan                     # not known from frame 7 on
    transl = np.tile([0.3, 0.1, 5.0], (1, t, 1))
    valid = np.ones((1, t), bool)
    valid[0, 9] = False
    velocity = static_velocity(flow, transl, valid, K, window=1)
    assert velocity.shape == (1, t, 3)
    np.testing.assert_allclose(velocity[0, 0], [2.0 * 5 / 500, -1.0 * 5 / 400, 0.0])
    np.testing.assert_allclose(velocity[0, 2, 0], (2 + 2 + 8) / 3 * 5 / 500)
    np.testing.assert_allclose(velocity[0, 7, 0], 2.0 * 5 / 500)   # frame 6 is within its window
    np.testing.assert_array_equal(velocity[0, 8:], 0.0)           # nothing known near, or not valid
    assert (velocity[..., 2] == 0).all()


def test_a_person_standing_before_a_dolly_is_not_mirrored_when_the_floor_shows_the_camera_move(body):
    from multithumbs.perception.blazepose_backend import poses_to_tracks
    from tests.perception.readings import body_reading
    from tests.perception.test_facing import K, UPRIGHT_FACING_CAMERA

    # Truth: a person standing, facing the camera, read rightly, while the camera dollies sideways: the root
    # moves 12.5 mm a frame towards -x in the camera frame, and the fit's depth wanders away by 3 mm a frame.
    # In the camera frame that is a walk, fast enough to count, with a part away from the camera.
    transl = np.stack([0.5 - 0.0125 * np.arange(16), np.full(16, 0.3), 4.0 + 0.003 * np.arange(16)], -1)
    reading = body_reading(body, UPRIGHT_FACING_CAMERA, transl, K)
    kept = poses_to_tracks(reading, 0, 0, K, (360, 640), body, facing=FacingConfig(enabled=False))
    camera_only = poses_to_tracks(reading, 0, 0, K, (360, 640), body)
    assert not np.array_equal(camera_only.keypoints2d, kept.keypoints2d)   # mirrored: the dolly read as a walk
    floor = np.tile([-0.0125 * K[0, 0] / 4.0, 0.0], (1, 16, 1))           # the floor at 4 m moves as the root
    floor[:, -1] = np.nan
    with_floor = poses_to_tracks(reading, 0, 0, K, (360, 640), body, floor_flow=floor)
    np.testing.assert_array_equal(with_floor.keypoints2d, kept.keypoints2d)
