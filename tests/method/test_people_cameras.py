"""The boundary cameras from the people (multithumbs.method.people_cameras) at reverse-angle cuts."""

import dataclasses
import math

import numpy as np
import pytest

from multithumbs.geometry import camera_centre, rotation_angle
from multithumbs.method.align import AlignConfig, align_boundary, keypoint_fitted_pelvis
from multithumbs.method.people_cameras import cameras_from_people, partial_matchings
from multithumbs.pipeline import MethodConfig, boundary_people, run_video
from multithumbs.synth.perception import NO_NOISE, simulate_perception, true_track_people
from multithumbs.synth.scene import SceneConfig, synthesize
from multithumbs.synth.simulated_geometry import simulate_camera_trajectory, simulate_shared_space

FAST = AlignConfig(iterations=(0, 60, 120))
DIALOGUE = dict(dialogue=True, camera_distance=2.0, camera_height=(1.45, 1.65), image_size=(240, 426))


@pytest.fixture(scope="module")
def reverse_shot(body):
    """Two people in conversation, a 180-degree cut (nothing of the room in both boundary frames)."""
    return synthesize(SceneConfig(num_people=2, num_shots=2, num_frames=16, seed=203, cut_angle_deg=180,
                                  **DIALOGUE), body)


@pytest.fixture(scope="module")
def a_b_a(body):
    """Three people, 180-degree cuts, person 0 away during shot 1: seen in shots 0 and 2 only."""
    return synthesize(SceneConfig(num_people=3, num_shots=3, num_frames=36, seed=204, cut_angle_deg=180,
                                  absent_in_shots=((0, 1),), **DIALOGUE), body)


def _true_relative(video, cut: int = 0):
    """Camera 1 in camera 0's frame (``X_1 = R X_0 + t``) of the cut's boundary frames."""
    world = video.truth.world
    f = int(world.cut_frames[cut])
    R = world.R[f] @ world.R[f - 1].T
    return R, world.t[f] - R @ world.t[f - 1]


def _solve(video, body, noise=NO_NOISE, seed=0):
    tracks = simulate_perception(video, body, noise, seed=seed)
    space = simulate_shared_space(video, 0)
    people = boundary_people(tracks[0], tracks[1], body, K=space.K)
    pelvis = keypoint_fitted_pelvis(people, space.K, 0.3)
    return tracks, space, people, cameras_from_people(people, pelvis, space.K)


def test_partial_matchings_are_every_injective_matching():
    # sum over m of C(n0, m) * n1! / (n1 - m)!
    for n0, n1 in ((1, 1), (2, 2), (3, 2), (3, 3)):
        expected = sum(math.comb(n0, m) * math.perm(n1, m) for m in range(1, min(n0, n1) + 1))
        found = partial_matchings(n0, n1)
        assert len(found) == expected == len(set(found))
        assert all(len({i for i, _ in h}) == len(h) == len({j for _, j in h}) for h in found)
    assert partial_matchings(0, 3) == []
    assert max(len(h) for h in partial_matchings(4, 4, max_pairs=2)) == 2


def test_the_simulated_space_falls_back_at_a_reverse_shot(reverse_shot):
    space = simulate_shared_space(reverse_shot, 0)
    assert space.fallback.startswith("no shared background") and space.points.shape[0] == 0


def test_exact_people_give_the_true_cameras_and_pairs(reverse_shot, body):
    tracks, _, people, found = _solve(reverse_shot, body)
    R_true, t_true = _true_relative(reverse_shot)
    assert found.found
    assert np.rad2deg(rotation_angle(found.R[1], R_true)) < 0.5
    centre, centre_true = camera_centre(found.R[1], found.t[1]), camera_centre(R_true, t_true)
    assert np.linalg.norm(centre - centre_true) < 0.05
    truth = [true_track_people(tr, reverse_shot) for tr in tracks[:2]]
    matched = {(int(truth[0][people.track_index[0, i]]), int(truth[1][people.track_index[1, j]]))
               for i, j in found.pairs}
    assert matched == {(0, 0), (1, 1)}


def test_noisy_people_give_the_rotation_within_five_degrees(reverse_shot, body):
    from multithumbs.synth.perception import PerceptionNoise

    errors = []
    for seed in range(3):
        _, _, _, found = _solve(reverse_shot, body, PerceptionNoise(miss_rate=0.0), seed=seed)
        errors.append(float(np.rad2deg(rotation_angle(found.R[1], _true_relative(reverse_shot)[0]))))
    assert max(errors) < 5.0, errors


def test_appearance_decides_between_mirror_hypotheses(reverse_shot, body):
    # Geometry alone fits both "the camera turned around the two people" and "the two swapped places";
    # swapping one side's descriptors swaps the matching.
    _, space, people, found = _solve(reverse_shot, body)
    assert people.appearance.shape[1] == 2
    appearance = people.appearance.copy()
    appearance[1] = appearance[1, ::-1]
    swapped = dataclasses.replace(people, appearance=appearance)
    other = cameras_from_people(swapped, keypoint_fitted_pelvis(swapped, space.K, 0.3), space.K)
    assert {tuple(p) for p in found.pairs} == {(0, 0), (1, 1)} or {tuple(p) for p in found.pairs} == {(0, 1), (1, 0)}
    assert {tuple(p) for p in other.pairs} == {(i, 1 - j) for i, j in found.pairs}


def test_nobody_on_one_side_finds_nothing(reverse_shot, body):
    _, _, people, _ = _solve(reverse_shot, body)
    empty = dataclasses.replace(people, present=people.present & np.array([[True], [False]]))
    found = cameras_from_people(empty, people.pelvis_cam, reverse_shot.truth.world.K[:2])
    assert not found.found and found.pairs.shape == (0, 2)


def test_alignment_takes_the_people_cameras_only_where_the_space_fell_back(reverse_shot, body):
    _, space, people, _ = _solve(reverse_shot, body)
    aligned = align_boundary(people, space, FAST)
    assert aligned.cameras_from == "people" and len(aligned.people_pairs) == 2
    R_true = _true_relative(reverse_shot)[0]
    assert np.rad2deg(rotation_angle(aligned.R[1] @ aligned.R[0].T, R_true)) < 1.0
    never = align_boundary(people, space, dataclasses.replace(FAST, people_cameras="never"))
    assert never.cameras_from == "none"
    assert np.rad2deg(rotation_angle(never.R[1] @ never.R[0].T, R_true)) > 90  # what the fallback alone gives
    with pytest.raises(ValueError, match="people_cameras"):
        align_boundary(people, space, dataclasses.replace(FAST, people_cameras="sometimes"))


def test_a_person_back_two_shots_later_keeps_their_id(a_b_a, body):
    shots = a_b_a.truth.world.shots()
    tracks = simulate_perception(a_b_a, body, NO_NOISE)
    spaces = [simulate_shared_space(a_b_a, c) for c in range(shots.num_shots - 1)]
    assert all(s.fallback for s in spaces)
    trajectories = [simulate_camera_trajectory(a_b_a, k) for k in range(shots.num_shots)]
    config = dataclasses.replace(MethodConfig(), align=FAST)
    result = run_video(shots, tracks, trajectories, spaces, body, config)
    truth = [true_track_people(tr, a_b_a) for tr in tracks]
    ids = {}  # true person -> global ids given to their tracks
    for shot, local, gid in result.id_map:
        i = int(np.nonzero(tracks[shot].track_ids == local)[0][0])
        ids.setdefault(int(truth[shot][i]), set()).add(int(gid))
    assert all(len(g) == 1 for g in ids.values()), ids
    assert len(ids) == 3 and len(set.union(*ids.values())) == 3
    # Person 0 is absent in shot 1: shot 2's track of them took shot 0's id.
    assert 0 in truth[0] and 0 not in truth[1] and 0 in truth[2]


def test_a_fallback_pose_is_kept_only_when_the_people_agree(tiny, body):
    # A pose found by a fallback path (pooled neighbour frames) is checked against the people's cameras.
    from multithumbs.geometry import axis_angle_to_matrix

    people = boundary_people(tiny.tracks[0], tiny.tracks[1], body, K=tiny.spaces[0].K)
    pooled = dataclasses.replace(tiny.spaces[0], fallback="neighbour_frames")
    assert align_boundary(people, pooled, FAST).cameras_from == "scene"  # right: kept
    turned = axis_angle_to_matrix(np.array([0.0, np.pi / 2, 0.0]))
    wrong = dataclasses.replace(pooled, R=np.stack([pooled.R[0], turned @ pooled.R[1]]))
    aligned = align_boundary(people, wrong, FAST)
    assert aligned.cameras_from == "people"
    truth = tiny.video.truth.world
    cut = int(truth.cut_frames[0])
    R_true = truth.R[cut] @ truth.R[cut - 1].T
    assert np.rad2deg(rotation_angle(aligned.R[1] @ aligned.R[0].T, R_true)) < 2.0
    assert align_boundary(people, tiny.spaces[0], FAST).cameras_from == "scene"  # no fallback: not asked
