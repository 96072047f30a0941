"""The floor the shot's people stand on, and the short tracks whose feet are not on it
(:mod:`multithumbs.perception.floor_check`): the floor's rows against an independent projection of a floor
plane, and which tracks are dropped on a scene of people walking and a pattern read as a person."""

import dataclasses

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from multithumbs.perception.floor_check import (FOOT_JOINTS, FloorCheckConfig, cut_by_edge, drop_off_floor, fit_floor,
                                                floor_offsets, keep_people)
from multithumbs.types import PersonTracks

K = np.array([[500.0, 0.0, 320.0], [0.0, 500.0, 180.0], [0.0, 0.0, 1.0]])
CAMERA_HEIGHT = 1.6


def _camera(pitch_deg: float, roll_deg: float) -> np.ndarray:
    """World-to-camera rotation of the camera tilted by ``pitch_deg`` and rolled by ``roll_deg``."""
    return Rotation.from_euler("zx", [roll_deg, -pitch_deg], degrees=True).as_matrix()


def _project(points_world: np.ndarray, R: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pixels ``(N, 2)`` (column, row) and camera depths ``(N,)`` of world points; the world's axes are the
    level camera's (x right, y down, z ahead), the floor is y = 0 and the camera is ``CAMERA_HEIGHT`` above it."""
    cam = (points_world - np.array([0.0, -CAMERA_HEIGHT, 0.0])) @ R.T
    uv = cam[:, :2] / cam[:, 2:] * K[[0, 1], [0, 1]] + K[:2, 2]
    return uv, cam[:, 2]


@pytest.mark.parametrize("pitch, roll", [(0.0, 0.0), (12.0, 0.0), (8.0, 4.0)])
def test_floor_points_seen_by_a_tilted_rolled_camera_lie_on_the_fitted_rows(pitch, roll):
    rng = np.random.default_rng(0)
    floor = np.stack([rng.uniform(-3, 3, 60), np.zeros(60), rng.uniform(2, 9, 60)], axis=1)
    uv, depth = _project(floor, _camera(pitch, roll))
    a, b, c = fit_floor(uv[:, 1], depth, uv[:, 0], scale=5.0)
    np.testing.assert_allclose(a + b / depth + c * uv[:, 0], uv[:, 1], atol=1e-6)
    if pitch == 0 and roll == 0:  # a level camera: the horizon at the centre row, b = f h
        np.testing.assert_allclose([a, b, c], [180.0, 500.0 * CAMERA_HEIGHT, 0.0], atol=1e-6)


def _walkers(frames: int = 30) -> tuple[list[np.ndarray], list[np.ndarray], list[np.ndarray]]:
    """Three people walking on the floor: per person ``(T, 24, 3)`` keypoints, ``(T, 3)`` translations."""
    R = _camera(10.0, 0.0)
    keypoints, transl = [], []
    for x0, z0, vz in ((-1.0, 3.0, 0.05), (0.5, 5.0, -0.04), (1.5, 7.0, 0.02)):
        kp, tr = np.zeros((frames, 24, 3)), np.zeros((frames, 3))
        for t in range(frames):
            foot = np.array([[x0, 0.0, z0 + vz * t]])
            head = foot + [0.0, -1.7, 0.0]
            (uv_foot, uv_head), depth = _project(np.concatenate([foot, head]), R)
            kp[t, :, :2] = np.linspace(uv_head, uv_foot, 24)  # a body from head to feet
            kp[t, list(FOOT_JOINTS), :2] = uv_foot
            kp[t, :, 2] = 1.0
            tr[t] = [0.0, 0.0, depth[0]]
        keypoints.append(kp)
        transl.append(tr)
    return keypoints, transl, R


def _tracks(keypoints: list[np.ndarray], transl: list[np.ndarray], valid: list[np.ndarray]) -> PersonTracks:
    p, t = len(keypoints), keypoints[0].shape[0]
    return PersonTracks(
        shot_index=0, start_frame=0, track_ids=np.arange(p) + 10, global_orient=np.zeros((p, t, 3)),
        body_pose=np.zeros((p, t, 23, 3)), betas=np.zeros((p, 10)), transl=np.stack(transl),
        keypoints2d=np.stack(keypoints), masks=np.zeros((p, t, 360, 80), np.uint8), image_size=(360, 640), K=K,
        appearance=np.zeros((p, t, 4)), appearance_valid=np.zeros((p, t), bool), valid=np.stack(valid))


def _with_pattern(long: bool = False) -> PersonTracks:
    """The walkers and a pattern on the floor read as a whole small body: its feet are on the floor near
    the camera, but its size puts its fitted root 9 m away; 8 frames (or all 30 when ``long``)."""
    keypoints, transl, R = _walkers()
    kp = np.zeros((30, 24, 3))
    (uv_foot, uv_head), _ = _project(np.array([[0.0, 0.0, 2.5], [0.0, -0.8, 2.5]]), R)
    kp[:, :, :2] = np.linspace(uv_head, uv_foot, 24)
    kp[:, list(FOOT_JOINTS), :2] = uv_foot
    kp[:, :, 2] = 1.0
    seen = np.zeros(30, bool)
    seen[: 30 if long else 8] = True
    valid = [np.ones(30, bool)] * 3 + [seen]
    return _tracks(keypoints + [kp], transl + [np.tile([0.0, 0.0, 9.0], (30, 1))], valid)


def test_a_short_track_whose_feet_are_off_the_floor_is_dropped():
    tracks = _with_pattern()
    offsets, scatters = floor_offsets(tracks)
    assert np.isnan(offsets[:3]).all()  # people followed for longer than max_readings are not judged
    assert offsets[3] > 0.25  # its feet are far below (positive) where a body 9 m away stands
    assert scatters[3] < 1e-6  # the walkers' feet are exactly on the floor
    kept = drop_off_floor(tracks)
    assert kept.track_ids.tolist() == [10, 11, 12]
    np.testing.assert_array_equal(kept.keypoints2d, tracks.keypoints2d[:3])


def test_short_tracks_of_people_on_the_floor_are_kept():
    keypoints, transl, _ = _walkers()
    short = np.zeros(30, bool)
    short[10:20] = True
    tracks = _tracks(keypoints, transl, [np.ones(30, bool), short, np.ones(30, bool)])
    assert abs(floor_offsets(tracks)[0][1]) < 1e-6
    assert drop_off_floor(tracks).track_ids.tolist() == [10, 11, 12]


def test_long_tracks_and_floors_with_too_few_readings_are_not_judged():
    assert drop_off_floor(_with_pattern(long=True)).num_people == 4
    config = dataclasses.replace(FloorCheckConfig(), min_floor_readings=91)  # the others have 90
    assert np.isnan(floor_offsets(_with_pattern(), config)[0]).all()
    assert drop_off_floor(_with_pattern(), dataclasses.replace(FloorCheckConfig(), enabled=False)).num_people == 4


def test_keep_people_keeps_every_per_person_field():
    tracks = _with_pattern()
    kept = keep_people(tracks, np.array([False, True, False, True]))
    assert kept.num_people == 2 and kept.track_ids.tolist() == [11, 13]
    for name in ("transl", "keypoints2d", "masks", "valid", "appearance", "betas"):
        np.testing.assert_array_equal(getattr(kept, name), getattr(tracks, name)[[1, 3]])


def test_a_floor_is_not_fitted_to_one_person_or_to_feet_at_one_depth():
    tracks = _with_pattern()
    one_person = keep_people(tracks, np.array([True, False, False, True]))
    assert np.isnan(floor_offsets(one_person)[0]).all()
    # Everyone else standing still at one depth: nothing says how the floor's rows change with depth.
    still = dataclasses.replace(tracks, keypoints2d=np.concatenate(
        [np.repeat(tracks.keypoints2d[:3, :1], 30, axis=1), tracks.keypoints2d[3:]]),
        transl=np.concatenate([np.tile([0.0, 0.0, 5.0], (3, 30, 1)), tracks.transl[3:]]))
    assert np.isnan(floor_offsets(still)[0][3])



def test_a_floor_the_others_fit_loosely_drops_no_one():
    # vtest.avi: pedestrians on grass and paths, small and far, scatter about one floor by 0.29 of their
    # heights, and a real walker there, read for 6 frames, was 0.44 off it.
    keypoints, transl, _ = _walkers()
    heights = np.stack([kp[..., 1].max(-1) - kp[..., 1].min(-1) for kp in keypoints])  # (3, T)
    off = keypoints[1].copy()
    off[:, list(FOOT_JOINTS), 1] -= (0.45 * heights[1])[:, None]
    short = np.zeros(30, bool)
    short[10:16] = True
    valid = [np.ones(30, bool)] * 3 + [short]
    flat = _tracks(keypoints + [off], transl + [transl[1]], valid)
    assert drop_off_floor(flat).num_people == 3  # on a floor the others fit exactly, 0.45 off is dropped
    rng = np.random.default_rng(1)
    bumpy = [kp.copy() for kp in keypoints]
    for kp, h in zip(bumpy, heights):
        kp[:, list(FOOT_JOINTS), 1] += (0.3 * h * rng.standard_normal(h.shape))[:, None]
    loose = _tracks(bumpy + [off], transl + [transl[1]], valid)
    offsets, scatters = floor_offsets(loose)
    assert abs(offsets[3]) > 0.25 and abs(offsets[3]) < 5 * scatters[3]
    assert drop_off_floor(loose).num_people == 4


@pytest.mark.parametrize("width", [640, 636])
def test_cut_by_edge_is_a_mask_pixel_on_the_frames_border_in_a_valid_frame(width):
    h, p, t = 40, 6, 3
    full = np.zeros((p, t, h, width), bool)
    full[:, :, 10:20, 10:20] = True  # every person has an inner blob
    full[1, 0, 0, 30] = True  # top row
    full[2, 1, h - 1, 5] = True  # bottom row
    full[3, 2, 25, 0] = True  # first column
    full[4, 0, 12, width - 1] = True  # last column
    full[5, 1, 0, 0] = True  # on the border, but in a frame where the person is not valid
    valid = np.ones((p, t), bool)
    valid[5, 1] = False
    packed = np.packbits(full, axis=-1)
    border = full[..., [0, -1], :].any((-1, -2)) | full[..., :, [0, -1]].any((-1, -2))  # unpacked, directly
    expected = (border & valid).any(-1)
    np.testing.assert_array_equal(cut_by_edge(packed, valid, width), expected)
    assert expected.tolist() == [False, True, True, True, True, False]


def test_a_short_track_cut_by_the_frames_edge_is_not_judged():
    # s02's person entering through the frame's left edge, close to the camera: BlazePose read the body
    # squeezed into the frame, feet 0.32 of its height above the floor, and the check dropped a real person.
    keypoints, transl, _ = _walkers()
    heights = np.stack([kp[..., 1].max(-1) - kp[..., 1].min(-1) for kp in keypoints])
    raised = keypoints[1].copy()
    raised[:, list(FOOT_JOINTS), 1] -= (0.45 * heights[1])[:, None]
    short = np.zeros(30, bool)
    short[10:16] = True
    tracks = _tracks(keypoints + [raised], transl + [transl[1]], [np.ones(30, bool)] * 3 + [short])
    masks = np.zeros((4, 30, 360, 640), bool)
    masks[:, :, 100:200, 300:340] = True
    masks[3, 12, 150:200, 0:20] = True  # in one of its frames, the mask reaches the left edge
    tracks = dataclasses.replace(tracks, masks=np.packbits(masks, axis=-1))
    assert np.isnan(floor_offsets(tracks)[0][3])
    assert drop_off_floor(tracks).num_people == 4
    judged = dataclasses.replace(FloorCheckConfig(), judge_cut=True)
    assert floor_offsets(tracks, judged)[0][3] < -0.25  # above the floor (negative)
    assert drop_off_floor(tracks, judged).num_people == 3
