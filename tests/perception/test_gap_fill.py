"""Short gaps inside a track bridged by the body between the readings around them
(:mod:`multithumbs.perception.gap_fill`): which frames are bridged, hand-worked; a walker turning at a
steady rate and bending a knee at a steady rate is bridged exactly, against the body posed and projected
independently; what was observed stays told apart from what was bridged."""

import numpy as np
import pytest
import torch
from scipy.spatial.transform import Rotation

from multithumbs.perception.gap_fill import GapFillConfig, bridge_gaps, bridgeable
from multithumbs.types import PersonTracks
from tests.perception.readings import body_reading

K = np.array([[500.0, 0.0, 320.0], [0.0, 500.0, 180.0], [0.0, 0.0, 1.0]])
FRAMES = 30
LEFT_KNEE = 3  # SMPL joint 4, the fourth of body_pose


def test_bridgeable_frames_hand_worked():
    valid = np.array([[1, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0],
                      [0, 0, 1, 1, 0, 1, 0, 0, 0, 0, 0]], bool)
    expected = np.array([[0, 1, 1, 0, 0, 0, 0, 0, 0, 0, 0],  # 2 frames bridged; the 4-frame gap is too long
                         [0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0]], bool)  # the ends are never extended
    np.testing.assert_array_equal(bridgeable(valid, 3), expected)
    expected[0, 4:8] = True  # with max_gap 4, the 4-frame gap too
    np.testing.assert_array_equal(bridgeable(valid, 4), expected)
    assert not bridgeable(valid, 0).any()


def _walker() -> PersonTracks:
    """One person walking at 1.2 m/s at 30 fps, turning 2° a frame about the camera's vertical and bending
    the left knee 1.5° a frame; a second person standing still, seen in every frame."""
    t = np.arange(FRAMES)
    facing = Rotation.from_euler("x", 180, degrees=True)  # upright facing the camera (y down, z ahead)
    orient = (Rotation.from_euler("y", 2.0 * t[:, None], degrees=True) * facing).as_rotvec()
    pose = np.zeros((2, FRAMES, 23, 3))
    pose[0, :, LEFT_KNEE, 0] = np.radians(1.5 * t)
    transl = np.zeros((2, FRAMES, 3))
    transl[0] = np.stack([-1.0 + 0.04 * t, np.full(FRAMES, 0.3), 5.0 - 0.01 * t], 1)
    transl[1] = [1.0, 0.3, 6.0]
    keypoints = np.zeros((2, FRAMES, 24, 3))
    keypoints[..., 2] = 0.9
    return PersonTracks(
        shot_index=0, start_frame=0, track_ids=np.array([4, 7]),
        global_orient=np.stack([orient, np.tile(facing.as_rotvec(), (FRAMES, 1))]), body_pose=pose,
        betas=np.array([[0.5] + [0.0] * 9, [0.0] * 10]), transl=transl, keypoints2d=keypoints,
        masks=np.ones((2, FRAMES, 360, 80), np.uint8), image_size=(360, 640), K=K,
        appearance=np.ones((2, FRAMES, 4)), appearance_valid=np.ones((2, FRAMES), bool),
        valid=np.ones((2, FRAMES), bool))


def _with_gap(tracks: PersonTracks, frames: slice) -> PersonTracks:
    """``tracks`` with the first person unseen in ``frames``, as the backend leaves an unseen frame: its
    parameters held from a seen one, no keypoints, no mask, no appearance."""
    out = {name: getattr(tracks, name).copy() for name in ("global_orient", "body_pose", "transl", "keypoints2d",
                                                             "masks", "appearance_valid", "valid")}
    for name in ("global_orient", "body_pose", "transl"):
        out[name][0, frames] = out[name][0, frames.start - 1]
    out["keypoints2d"][0, frames] = 0.0
    out["masks"][0, frames] = 0
    out["appearance_valid"][0, frames] = False
    out["valid"][0, frames] = False
    return PersonTracks(**{**tracks.__dict__, **out})


def test_a_walker_turning_and_bending_at_a_steady_rate_is_bridged_exactly(body):
    truth = _walker()
    gap = slice(10, 22)  # 12 frames, as s10's yellow walker behind the blue one
    holed = _with_gap(truth, gap)
    holed.masks[0, gap] = 1  # padding may hold anything (docs/CONVENTIONS.md)
    bridged = bridge_gaps(holed, body, GapFillConfig(max_gap=12))
    assert bridged.valid.all()
    np.testing.assert_allclose(bridged.transl, truth.transl, atol=1e-12)
    angle = Rotation.from_rotvec(bridged.global_orient[0, gap]).inv() * Rotation.from_rotvec(
        truth.global_orient[0, gap])
    assert np.degrees(angle.magnitude()).max() < 1e-6
    np.testing.assert_allclose(bridged.body_pose, truth.body_pose, atol=1e-9)
    # The bridged keypoints are the body's joints through K, posed and projected here independently.
    with torch.no_grad():
        joints = body.forward(truth.global_orient[0, gap], truth.body_pose[0, gap],
                              np.tile(truth.betas[0], (12, 1)), truth.transl[0, gap]).joints.double().numpy()
    uv = joints[..., :2] / joints[..., 2:] * 500.0 + [320.0, 180.0]
    np.testing.assert_allclose(bridged.keypoints2d[0, gap, :, :2], uv, atol=1e-3)
    # No evidence is claimed where nothing was seen; what was seen is untouched.
    assert (bridged.keypoints2d[0, gap, :, 2] == 0).all()
    assert not bridged.masks[0, gap].any() and not bridged.appearance_valid[0, gap].any()
    seen = np.ones(FRAMES, bool)
    seen[gap] = False
    np.testing.assert_array_equal(bridged.keypoints2d[0, seen], truth.keypoints2d[0, seen])
    np.testing.assert_array_equal(bridged.keypoints2d[1], truth.keypoints2d[1])
    np.testing.assert_array_equal(bridged.transl[1], truth.transl[1])


@pytest.mark.parametrize("max_gap", [0, 11])
def test_a_gap_longer_than_max_gap_is_left_alone(body, max_gap):
    tracks = _with_gap(_walker(), slice(10, 22))
    assert bridge_gaps(tracks, body, GapFillConfig(max_gap=max_gap)) is tracks


def test_a_track_that_ends_is_not_carried_on(body):
    tracks = _with_gap(_walker(), slice(20, FRAMES))
    assert bridge_gaps(tracks, body) is tracks


def test_the_cpu_backend_bridges_a_walker_unseen_for_six_frames(body):
    from multithumbs.perception.blazepose_backend import poses_to_tracks

    transl = np.stack([-0.5 + 0.04 * np.arange(20), np.full(20, 0.3), np.full(20, 4.0)], -1)
    seen = np.ones(20, bool)
    seen[8:14] = False
    reading = body_reading(body, np.array([np.pi, 0.0, 0.0]), transl, K, seen)
    tracks = poses_to_tracks(reading, 0, 0, K, (360, 640), body)
    assert tracks.valid.all()
    assert (tracks.keypoints2d[0, ~seen, :, 2] == 0).all() and (tracks.keypoints2d[0, seen, 1, 2] > 0).all()
    # The fit places the walker from its size; across the gap it walks on at its pace.
    step = np.diff(tracks.transl[0, 7:15, 0])
    np.testing.assert_allclose(step, step.mean(), atol=1e-9)
    assert abs(step.mean() - 0.04) < 0.01
    unbridged = poses_to_tracks(reading, 0, 0, K, (360, 640), body, gaps=GapFillConfig(max_gap=0))
    np.testing.assert_array_equal(unbridged.valid[0], seen)
    np.testing.assert_array_equal(unbridged.transl[0, seen], tracks.transl[0, seen])
