"""Front/back confusions resolved by the walk: the mirror, forward and velocity algebra, and the backend's
step 4 on a person seen from behind whom the landmarks read as facing the camera."""

import numpy as np
import pytest
import torch

from multithumbs.perception.facing import (BLAZEPOSE_MIRROR, LOWER_BODY, FacingConfig, body_forward, body_seen,
                                           evidence_speed, facing_flips, landmarks_seen, mirrored, reading_forward,
                                           root_velocity, twisted, untwisted, walk_headings)
from tests.perception.readings import body_reading

K = np.array([[500.0, 0, 320], [0, 500.0, 180], [0, 0, 1]])
UPRIGHT_FACING_CAMERA = np.array([np.pi, 0.0, 0.0])   # SMPL's y-up body in the camera frame (+y down)
UPRIGHT_FACING_AWAY = np.array([0.0, 0.0, np.pi])     # the same turned about the vertical


def test_mirror_exchanges_sides_and_is_its_own_inverse():
    order = np.asarray(BLAZEPOSE_MIRROR)
    assert sorted(order) == list(range(33)) and np.all(order[order] == np.arange(33))
    assert order[11] == 12 and order[23] == 24 and order[31] == 32 and order[0] == 0   # shoulders, hips, feet, nose
    rng = np.random.default_rng(0)
    image, world = rng.normal(size=(2, 5, 33, 5)), rng.normal(size=(2, 5, 33, 3))
    flip = rng.random((2, 5)) < 0.5
    once = mirrored(image, world, flip)
    twice = mirrored(*once, flip)
    np.testing.assert_allclose(twice[0], image, atol=1e-12)
    np.testing.assert_allclose(twice[1], world, atol=1e-12)
    np.testing.assert_array_equal(once[1][~flip], world[~flip])
    p, t = np.argwhere(flip)[0]
    np.testing.assert_array_equal(once[1][p, t, 11, :2], world[p, t, 12, :2])   # left shoulder <- right's
    assert once[1][p, t, 11, 2] == -world[p, t, 12, 2]                           # depth through the hips
    np.testing.assert_array_equal(once[0][p, t, 11, 3:], image[p, t, 12, 3:])    # scores go with the name


def test_mirroring_the_lower_body_exchanges_its_sides_only_and_the_upper_half_completes_the_mirror():
    rng = np.random.default_rng(1)
    image, world = rng.normal(size=(4, 33, 5)), rng.normal(size=(4, 33, 3))
    world -= 0.5 * (world[:, 23:24] + world[:, 24:25])   # hip-centred, as BlazePose's world landmarks
    flip = np.array([True, False, True, True])
    upper = tuple(i for i in range(33) if i not in LOWER_BODY)
    lower_image, lower_world = mirrored(image, world, flip, LOWER_BODY)
    np.testing.assert_array_equal(lower_world[:, :23], world[:, :23])               # the upper half untouched
    np.testing.assert_array_equal(lower_image[:, :23], image[:, :23])
    np.testing.assert_array_equal(lower_world[1], world[1])                         # frames not flipped
    np.testing.assert_array_equal(lower_world[0, 25, :2], world[0, 26, :2])         # left knee <- right's
    assert lower_world[0, 25, 2] == -world[0, 26, 2]
    np.testing.assert_array_equal(lower_image[0, 25, 3:], image[0, 26, 3:])
    whole = mirrored(image, world, flip)
    both = mirrored(lower_image, lower_world, flip, upper)
    np.testing.assert_allclose(both[0], whole[0], atol=1e-12)
    np.testing.assert_allclose(both[1], whole[1], atol=1e-12)


def _twisted_by(degrees: float) -> np.ndarray:
    """Landmarks of an upright person facing away (+z) whose shoulders are turned by ``degrees`` about
    the vertical through the hips."""
    world = _world_facing(np.ones(1))[0]
    world[[11, 12]] = _yawed(world[[11, 12]], degrees)
    return world


@pytest.mark.parametrize("degrees, expected", [(0.0, False), (60.0, False), (-85.0, False), (95.0, True),
                                               (-120.0, True), (180.0, True)])
def test_a_reading_is_twisted_when_its_hips_and_shoulders_face_apart(degrees, expected):
    world = _twisted_by(degrees)
    assert twisted(world, 90.0) == expected
    world[:, 1] += 0.1 * world[:, 0]   # a leaning trunk: the angle is read about the trunk, not the camera's y
    assert twisted(world, 90.0) == expected
    assert twisted(np.stack([_twisted_by(0.0), _twisted_by(180.0)]), 90.0).tolist() == [False, True]


def test_untwisting_turns_the_hips_to_the_shoulders_side_in_valid_twisted_frames_only():
    world = np.stack([_twisted_by(180.0), _twisted_by(180.0), _twisted_by(20.0)])[None]   # (1, 3, 33, 3)
    image = np.zeros((1, 3, 33, 5))
    image[..., 0] = np.arange(33)                      # each landmark's u names it
    valid = np.array([[True, False, True]])
    new_image, new_world, changed = untwisted(image, world, valid)
    assert changed.tolist() == [[True, False, False]]
    # The hips face away (+z) and the shoulders, turned half a circle, the camera: the hips turn to them.
    assert reading_forward(world[0, 0]) @ np.array([0, 0, 1.0]) > 0.99
    assert reading_forward(new_world[0, 0]) @ np.array([0, 0, 1.0]) < -0.99
    assert not twisted(new_world[0, 0], 90.0)
    assert new_image[0, 0, 23, 0] == 24 and new_image[0, 0, 11, 0] == 11
    np.testing.assert_array_equal(new_world[0, 1:], world[0, 1:])
    off = untwisted(image, world, valid, FacingConfig(enabled=False))
    np.testing.assert_array_equal(off[1], world)
    assert not off[2].any()


def test_forward_of_a_body_at_rest_is_its_plus_z(body):
    with torch.no_grad():
        rest = body.joints(np.zeros((1, 3)), np.zeros((1, 23, 3)), np.zeros((1, 10))).double().numpy()
        turned = body.joints(UPRIGHT_FACING_CAMERA[None], np.zeros((1, 23, 3)), np.zeros((1, 10))).double().numpy()
    np.testing.assert_allclose(body_forward(rest)[0], [0, 0, 1], atol=0.1)  # the rest spine leans ~4°
    np.testing.assert_allclose(body_forward(turned)[0], [0, 0, -1], atol=0.1)
    assert body_forward(rest).shape == (1, 3)


def test_root_velocity_is_the_slope_of_a_line_and_unknown_when_alone():
    t = np.arange(20.0)
    transl = np.stack([0.1 * t, 0 * t, 5 - 0.03 * t], -1)[None]
    valid = np.ones((1, 20), bool)
    valid[0, 5] = False
    velocity = root_velocity(transl, valid, window=4)
    np.testing.assert_allclose(velocity[0, valid[0]], np.tile([0.1, 0, -0.03], (19, 1)), atol=1e-12)
    assert np.isnan(velocity[0, 5]).all()
    lonely = np.zeros((1, 20), bool)
    lonely[0, [3, 12]] = True
    assert np.isnan(root_velocity(transl, lonely, window=4)).all()


def _world_facing(facing_z: np.ndarray) -> np.ndarray:
    """``(len, 33, 3)`` landmarks of upright people (camera axes, +y down) facing +z (1) or -z (-1)."""
    world = np.zeros((len(facing_z), 33, 3))
    world[:, 23, 0], world[:, 24, 0] = -facing_z * 0.1, facing_z * 0.1   # facing away: left hip at image left
    world[:, 11, 0], world[:, 12, 0] = -facing_z * 0.2, facing_z * 0.2
    world[:, [11, 12], 1] = -0.5                                       # shoulders above the hips
    return world


def test_a_readings_forward_and_its_mirrors_are_opposite():
    world = _world_facing(np.array([1.0, -1.0]))
    np.testing.assert_allclose(reading_forward(world), [[0, 0, 1], [0, 0, -1]], atol=1e-12)
    mirror = mirrored(np.zeros((2, 33, 5)), world, np.ones(2, bool))[1]
    np.testing.assert_allclose(reading_forward(mirror), -reading_forward(world), atol=1e-12)


def test_the_walk_labels_frames_and_turns_carry_it_to_frames_it_cannot_judge():
    # Truth: a person facing away from the camera (+z) walking away. BlazePose reads the first five
    # frames and two later ones as facing the camera; the walk is known only from frame 3 on.
    t = 20
    read_z = np.ones(t)
    read_z[[0, 1, 2, 3, 4, 11, 12]] = -1
    world = _world_facing(read_z)[None]
    velocity = np.tile([0.0, 0.0, 0.03], (1, t, 1))
    velocity[0, :3] = np.nan
    linked, judged = np.ones((1, t), bool), np.ones((1, t), bool)
    flips = facing_flips(world, velocity, linked, judged)
    np.testing.assert_array_equal(flips[0], read_z < 0)
    # Without any walk the turns alone keep the track consistent, with BlazePose's majority reading.
    standing = facing_flips(world, np.zeros((1, t, 3)), linked, judged)
    np.testing.assert_array_equal(standing[0], read_z < 0)
    assert not facing_flips(world, velocity, linked, judged, FacingConfig(enabled=False)).any()


def test_a_tracks_first_frames_follow_the_rest_against_a_few_frames_of_contrary_walk():
    # Truth: a person walking away from the camera, read by BlazePose as facing it in every frame. The
    # fitted roots' line is one-sided at a track's start: there the walk points at the camera for three
    # frames at half the full speed, then away. Each of those frames is 0.5 + 0.5 + 0.05 cheaper unmirrored:
    # 3.15 in all, less than half a turn costs (4), so the start is mirrored with the rest (s01's and s09's
    # first shots kept such starts at turn cost 2).
    t = 30
    world = _world_facing(-np.ones(t))[None]
    velocity = np.tile([0.0, 0.0, 0.03], (1, t, 1))
    velocity[0, :3] = [0.0, 0.0, -0.01]
    everywhere = np.ones((1, t), bool)
    np.testing.assert_array_equal(facing_flips(world, velocity, everywhere, everywhere), everywhere)
    at_two = facing_flips(world, velocity, everywhere, everywhere, FacingConfig(turn_cost=2.0))
    np.testing.assert_array_equal(at_two[0], np.arange(t) >= 3)


def test_a_standing_persons_labels_follow_the_head_where_no_walk_says_anything():
    # Truth: a person standing with their back to the camera; BlazePose reads every frame as facing it. The
    # head's colours say "back" in most frames, "face" in two (an oblique cheek) and nothing in three.
    t = 12
    world = _world_facing(-np.ones(t))[None]
    still, everywhere = np.zeros((1, t, 3)), np.ones((1, t), bool)
    face = -np.ones((1, t))
    face[0, [3, 8]] = 1.0
    face[0, [5, 6, 7]] = 0.0
    np.testing.assert_array_equal(facing_flips(world, still, everywhere, everywhere, face=face), everywhere)
    assert not facing_flips(world, still, everywhere, everywhere, face=-face).any()
    assert not facing_flips(world, still, everywhere, everywhere).any()            # no cue: the reading stays
    assert not facing_flips(world, still, everywhere, everywhere, FacingConfig(face_weight=0.0), face).any()


def test_frames_not_linked_keep_their_reading_and_unjudged_frames_give_no_evidence():
    t = 10
    world = _world_facing(-np.ones(t))[None]          # every frame read as facing the camera
    towards_away = np.tile([0.0, 0.0, 0.03], (1, t, 1))  # but walking away from it
    linked = np.ones((1, t), bool)
    linked[0, 4] = False                              # hips not seen there
    flips = facing_flips(world, towards_away, linked, np.ones((1, t), bool))
    np.testing.assert_array_equal(flips[0], linked[0])
    # The same walk with the legs out of view (a close-up) decides nothing: the reading is kept.
    assert not facing_flips(world, towards_away, linked, np.zeros((1, t), bool)).any()
    # A walk across the view or too slow to read says nothing either.
    across = np.tile([0.03, 0.0, 0.0], (1, t, 1))
    slow = np.tile([0.0, 0.0, 0.004], (1, t, 1))
    assert not facing_flips(world, across, linked, np.ones((1, t), bool)).any()
    assert not facing_flips(world, slow, linked, np.ones((1, t), bool)).any()


def test_evidence_speed_scales_the_component_along_the_view_only():
    rng = np.random.default_rng(3)
    velocity = rng.normal(size=(4, 6, 3))
    view = rng.normal(size=(4, 6, 3))
    view /= np.linalg.norm(view, axis=-1, keepdims=True)
    along = (velocity * view).sum(-1)
    across = np.linalg.norm(velocity - along[..., None] * view, axis=-1)
    np.testing.assert_allclose(evidence_speed(velocity, None, 0.5), np.linalg.norm(velocity, axis=-1))
    np.testing.assert_allclose(evidence_speed(velocity, view, 1.0), np.linalg.norm(velocity, axis=-1))
    np.testing.assert_allclose(evidence_speed(velocity, view, 0.0), across, atol=1e-12)
    np.testing.assert_allclose(evidence_speed(velocity, view, 0.25), np.hypot(across, 0.25 * along), atol=1e-12)


def test_a_standing_persons_depth_drift_is_weak_evidence_and_a_walk_away_still_decides():
    # Read as facing the camera throughout. A fit's depth drifting 8 mm a frame along the view (a person
    # standing, their size misread) mirrored every frame; counted at half, it is under min_speed and the
    # reading stays. A walk away at 30 mm a frame still counts and mirrors them.
    t = 10
    world = _world_facing(-np.ones(t))[None]
    everywhere = np.ones((1, t), bool)
    view = np.tile([0.0, 0.0, 1.0], (1, t, 1))
    drift = np.tile([0.0, 0.0, 0.008], (1, t, 1))
    np.testing.assert_array_equal(facing_flips(world, drift, everywhere, everywhere), everywhere)
    assert not facing_flips(world, drift, everywhere, everywhere, view=view).any()
    walk = np.tile([0.0, 0.0, 0.03], (1, t, 1))
    np.testing.assert_array_equal(facing_flips(world, walk, everywhere, everywhere, view=view), everywhere)
    # The headings alike; across the view the same 8 mm a frame counts in full.
    side = _yawed(_world_facing(np.ones(t)), 60.0)[None]
    sideways = np.tile([0.008, 0.0, 0.0], (1, t, 1))
    assert walk_headings(side, drift, everywhere)[1].all()                     # without the view: turned
    assert not walk_headings(side, drift, everywhere, FacingConfig(), view)[1].any()
    assert walk_headings(side, sideways, everywhere, FacingConfig(), view)[1].all()


def test_frames_whose_hips_are_unseen_are_labelled_across_the_shoulders():
    # Truth: walking away. The track's first two frames have their hips cut by the frame's foot: the
    # reading's shoulders face the camera, and its hips (unseen) are a profile's. Read across the shoulders,
    # the two frames take the rest's label through the turn cost; the hips' facing would say nothing.
    t = 10
    world = _world_facing(np.ones(t))[None]
    world[0, :2] = _world_facing(-np.ones(2))
    world[0, :2, [23, 24]] = [[0.0, 0.0, 0.1], [0.0, 0.0, -0.1]]     # hips along the depth: a profile
    velocity = np.tile([0.0, 0.0, 0.03], (1, t, 1))
    hips_seen, judged = np.ones((1, t), bool), np.ones((1, t), bool)
    hips_seen[0, :2] = judged[0, :2] = False
    flips = facing_flips(world, velocity, np.ones((1, t), bool), judged, hips_seen=hips_seen)
    np.testing.assert_array_equal(flips[0], np.arange(t) < 2)
    assert not facing_flips(world, velocity, hips_seen, judged).any()   # unlinked: the readings are kept


def test_a_body_is_seen_with_both_hips_and_one_legs_knee_and_ankle_inside_the_image():
    image = np.ones((5, 33, 5))
    image[..., :2] = 10.0
    image[1, 27, 3] = 0.4                         # the left ankle hidden: the right leg is seen
    image[2, [27, 28], 3] = 0.4                   # both ankles hidden
    image[3, 23, 3] = 0.4                         # a hip hidden
    image[4, 28, 1], image[4, 25, 3] = 500.0, 0.4  # the right ankle below the frame, the left knee hidden
    np.testing.assert_array_equal(body_seen(image, 0.5), [True, True, False, False, True])
    np.testing.assert_array_equal(body_seen(image, 0.5, (360, 640)), [True, True, False, False, False])
    np.testing.assert_array_equal(landmarks_seen(image, 0.5, (11, 12)), [True] * 5)
    np.testing.assert_array_equal(landmarks_seen(image, 0.5, (28,), (360, 640)), [True, True, False, True, False])


def test_a_walk_without_legs_in_view_says_nothing(body):
    from multithumbs.perception.blazepose_backend import poses_to_tracks

    transl = np.stack([np.zeros(16), np.full(16, 0.3), 4.0 + 0.04 * np.arange(16)], -1)
    reading = body_reading(body, UPRIGHT_FACING_CAMERA, transl, K)
    reading.image[..., 25:29, 3] = 0.2  # knees and ankles out of the frame: a close-up
    tracks = poses_to_tracks(reading, 0, 0, K, (360, 640), body)
    kept = poses_to_tracks(reading, 0, 0, K, (360, 640), body, facing=FacingConfig(enabled=False))
    np.testing.assert_array_equal(tracks.keypoints2d, kept.keypoints2d)


@pytest.mark.parametrize("walking", [True, False])
def test_a_back_read_as_a_front_is_mirrored_when_the_person_walks(body, walking):
    from multithumbs.perception.blazepose_backend import poses_to_tracks

    # Truth: seen from behind, walking away (or standing). The reading: the front-facing body at the same
    # place, which projects where the back does with every side's name exchanged (BlazePose's confusion).
    depth = 4.0 + (0.04 * np.arange(16) if walking else np.zeros(16))
    transl = np.stack([np.zeros(16), np.full(16, 0.3), depth], -1)
    reading = body_reading(body, UPRIGHT_FACING_CAMERA, transl, K)
    tracks = poses_to_tracks(reading, 0, 0, K, (360, 640), body)
    kept = poses_to_tracks(reading, 0, 0, K, (360, 640), body, facing=FacingConfig(enabled=False))
    left_of_right = tracks.keypoints2d[0, :, 1, 0] < tracks.keypoints2d[0, :, 2, 0]   # left hip at image left
    assert not (kept.keypoints2d[0, :, 1, 0] < kept.keypoints2d[0, :, 2, 0]).any()
    with torch.no_grad():
        joints = body.joints(tracks.global_orient, tracks.body_pose, tracks.betas, tracks.transl).double().numpy()
    facing_z = body_forward(joints)[0, :, 2]
    if walking:   # the truth's sides and facing, in every frame the walk covers
        assert left_of_right.all() and (facing_z > 0.5).all()
    else:         # nothing says which reading is right: the landmarks are kept
        assert not left_of_right.any() and (facing_z < -0.5).all()
        np.testing.assert_array_equal(tracks.keypoints2d, kept.keypoints2d)


def _yawed(world: np.ndarray, degrees: float) -> np.ndarray:
    """Landmarks ``(..., 33, 3)`` turned about the camera's vertical (+y down) through the origin."""
    a = np.radians(degrees)
    turn = np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])
    return world @ turn.T


def _signed_yaw(forward: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """Degrees from ``direction`` to ``forward`` about the camera's vertical, in the x-z plane."""
    return np.degrees(np.arctan2(forward[..., 0], forward[..., 2]) - np.arctan2(direction[..., 0], direction[..., 2]))


def test_a_walkers_reading_is_turned_towards_the_walk_by_the_two_precisions():
    config = FacingConfig()
    t = 6
    world = _yawed(_world_facing(np.ones(t)), 60.0)[None]      # read 60° off a walk away from the camera
    velocity = np.tile([0.0, 0.0, config.full_speed], (1, t, 1))
    velocity[0, 3:] *= 0.5                                     # half speed: the walk's spread doubles
    turned, turn = walk_headings(world, velocity, np.ones((1, t), bool), config)
    walk_p, read_p = 1 / config.walk_sigma_deg ** 2, 1 / config.reading_sigma_deg ** 2
    slow_p = 1 / (2 * config.walk_sigma_deg) ** 2
    expected = np.r_[[60 * read_p / (walk_p + read_p)] * 3, [60 * read_p / (slow_p + read_p)] * 3]
    np.testing.assert_allclose(_signed_yaw(reading_forward(turned), velocity)[0], expected, atol=1e-9)
    np.testing.assert_allclose(np.degrees(turn[0]), 60 - expected, atol=1e-9)   # about the trunk's up, -y
    # A rigid turn about the trunk through the mid-hip: shapes and the hips' centre are kept.
    hips = 0.5 * (turned[..., 23, :] + turned[..., 24, :])
    np.testing.assert_allclose(hips, 0.5 * (world[..., 23, :] + world[..., 24, :]), atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(turned[..., 11, :] - turned[..., 24, :], axis=-1),
                               np.linalg.norm(world[..., 11, :] - world[..., 24, :], axis=-1), atol=1e-12)


def test_frames_the_walk_says_nothing_of_keep_their_reading():
    t = 5
    world = _yawed(_world_facing(np.ones(t)), 40.0)[None]
    away = np.tile([0.0, 0.0, 0.03], (1, t, 1))
    judged = np.ones((1, t), bool)
    judged[0, 1] = False                                        # legs not seen there
    velocity = away.copy()
    velocity[0, 2] = np.nan                                     # too few valid frames near it
    velocity[0, 3] = [0.0, 0.0, 0.004]                          # too slow to read
    velocity[0, 4] = [0.0, 0.0, -0.03]                          # walking against the reading: left to the labels
    turned, turn = walk_headings(world, velocity, judged)
    np.testing.assert_array_equal(turned[0, 1:], world[0, 1:])
    assert turn[0, 0] != 0 and not turn[0, 1:].any()
    off, none = walk_headings(world, away, np.ones((1, t), bool), FacingConfig(heading=False))
    np.testing.assert_array_equal(off, world)
    assert not none.any()


def test_an_oblique_reading_of_a_walker_is_fitted_closer_to_their_facing(body):
    from multithumbs.perception.blazepose_backend import poses_to_tracks

    # Truth: seen from behind, walking away. The reading's 2D is exact, its 3D turned 50° about the
    # vertical (BlazePose's yaw of a back seen obliquely, docs/RESULTS.md session 21).
    transl = np.stack([np.zeros(16), np.full(16, 0.3), 4.0 + 0.04 * np.arange(16)], -1)
    reading = body_reading(body, UPRIGHT_FACING_AWAY, transl, K)
    reading.world[...] = _yawed(reading.world, 50.0)
    errors = {}
    for heading in (True, False):
        tracks = poses_to_tracks(reading, 0, 0, K, (360, 640), body, facing=FacingConfig(heading=heading))
        with torch.no_grad():
            joints = body.joints(tracks.global_orient, tracks.body_pose, tracks.betas, tracks.transl).double().numpy()
        errors[heading] = np.abs(_signed_yaw(body_forward(joints)[0], np.array([0.0, 0.0, 1.0])))
    assert np.median(errors[False]) > 20                        # the fit follows the reading's 3D
    assert np.median(errors[True]) < 0.5 * np.median(errors[False])


@pytest.mark.parametrize("whole_body", [True, False])
def test_a_standing_back_read_as_a_front_follows_the_head_on_whole_bodies_only(body, whole_body):
    from multithumbs.perception.blazepose_backend import poses_to_tracks

    # As above, standing: the head's colours say "back of a head" in every frame. They decide where the
    # whole body is seen; on a close-up (legs out of view) the reading is kept, as the walk's would be.
    transl = np.stack([np.zeros(16), np.full(16, 0.3), np.full(16, 4.0)], -1)
    reading = body_reading(body, UPRIGHT_FACING_CAMERA, transl, K)
    if not whole_body:
        reading.image[..., 25:29, 3] = 0.2
    tracks = poses_to_tracks(reading, 0, 0, K, (360, 640), body, face=-np.ones((1, 16)))
    with torch.no_grad():
        joints = body.joints(tracks.global_orient, tracks.body_pose, tracks.betas, tracks.transl).double().numpy()
    facing_z = body_forward(joints)[0, :, 2]
    assert (facing_z > 0.5).all() if whole_body else (facing_z < -0.5).all()


def test_a_reading_whose_hips_face_the_camera_under_a_back_is_fitted_as_a_back(body):
    from multithumbs.perception.blazepose_backend import poses_to_tracks

    # Truth: seen from behind, walking away. In three of the first frames the reading's hips and legs are
    # a front's (s09's first track, docs/RESULTS.md session 29): twisted half a turn under the shoulders.
    transl = np.stack([np.zeros(16), np.full(16, 0.3), 4.0 + 0.04 * np.arange(16)], -1)
    reading = body_reading(body, UPRIGHT_FACING_AWAY, transl, K)
    twist = np.zeros((1, 16), bool)
    twist[0, [1, 2, 4]] = True
    image, world = mirrored(reading.image, reading.world, twist, LOWER_BODY)
    reading.image[...], reading.world[...] = image, world
    errors = {}
    for max_twist in (90.0, 180.0):   # 180: never twisted
        tracks = poses_to_tracks(reading, 0, 0, K, (360, 640), body, facing=FacingConfig(max_twist_deg=max_twist))
        with torch.no_grad():
            joints = body.joints(tracks.global_orient, tracks.body_pose, tracks.betas, tracks.transl).double().numpy()
        errors[max_twist] = np.abs(_signed_yaw(body_forward(joints)[0], np.array([0.0, 0.0, 1.0])))
    assert errors[90.0].max() < 10
    assert errors[180.0][[1, 2, 4]].min() > 3 * errors[90.0][[1, 2, 4]].max()
