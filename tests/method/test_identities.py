"""Fragments of one person linked within a shot (``multithumbs.method.identities``), checked through the
CLEAR-MOT switch count (``multithumbs.metrics.identity``, itself checked against TrackEval)."""

import dataclasses

import numpy as np
import pytest

from multithumbs.method.config import ReidConfig
from multithumbs.method.identities import link_fragments
from multithumbs.metrics.evaluate import evaluate
from multithumbs.pipeline import run_video
from multithumbs.synth.perception import true_track_people
from tests.method.test_pipeline import FAST


def split_track(tracks, i, end, resume):
    """``tracks`` with track ``i`` lost from frame ``end`` and found again at ``resume`` under a new id (the
    tiny scene's shots have 5 frames): what a tracker does when someone walks behind another person."""
    P = tracks.num_people
    rows = np.r_[np.arange(P), i]
    fields = {}
    for f in dataclasses.fields(tracks):
        value = getattr(tracks, f.name)
        if isinstance(value, np.ndarray) and value.ndim >= 1 and value.shape[0] == P and f.name != "K":
            value = value[rows].copy()
        fields[f.name] = value
    fields["track_ids"][P] = tracks.track_ids.max() + 1
    fields["valid"][i, end:] = False
    fields["valid"][P, :resume] = False
    return type(tracks)(**fields)


def world_pelvis(tracks):
    """Stand-in world pelvis: the camera-frame translation (the shot's camera is the world)."""
    return np.asarray(tracks.transl, dtype=np.float64)


def test_a_person_found_again_under_a_new_id_is_linked_to_their_first_fragment(tiny):
    tracks = split_track(tiny.tracks[0], 0, 2, 3)
    previous = link_fragments(tracks, world_pelvis(tracks), ReidConfig(), fps=tiny.shots.fps)
    assert previous.tolist() == [-1, -1, 0]


@pytest.mark.parametrize("change", ["far", "unlike", "late", "off"])
def test_fragments_are_not_linked_past_the_gates(tiny, change):
    tracks = split_track(tiny.tracks[0], 0, 2, 3)
    pelvis, config = world_pelvis(tracks), ReidConfig()
    fps = tiny.shots.fps
    if change == "far":  # 3 m away two frames later: the gate is 1 m + 1.5 m/s over the gap
        pelvis[-1] += [3.0, 0.0, 0.0]
    elif change == "unlike":  # another person's clothes
        appearance = tracks.appearance.copy()
        appearance[-1] = tracks.appearance[1]
        tracks = dataclasses.replace(tracks, appearance=appearance)
    elif change == "late":
        fps = 0.5  # the same two frames are 4 s, beyond link_gap's 2 s
    else:
        config = ReidConfig(link_gap=0.0)
    assert (link_fragments(tracks, pelvis, config, fps=fps) == -1).all()


def test_a_track_overlapping_in_time_is_never_a_fragment(tiny):
    tracks = split_track(tiny.tracks[0], 0, 3, 2)  # the new id starts before the old one ends
    assert (link_fragments(tracks, world_pelvis(tracks), ReidConfig(), fps=tiny.shots.fps) == -1).all()


def test_the_method_gives_a_split_person_one_identity_and_counts_no_switch(tiny, body):
    tracks = list(tiny.tracks)
    tracks[1] = split_track(tracks[1], 0, 2, 3)
    linked = run_video(tiny.shots, tracks, tiny.trajectories, tiny.spaces, body, FAST)
    unlinked = run_video(tiny.shots, tracks, tiny.trajectories, tiny.spaces, body,
                         dataclasses.replace(FAST, reid=ReidConfig(link_gap=0.0)))
    ids = {(int(k), int(local)): int(g) for k, local, g in linked.id_map}
    first, second = int(tracks[1].track_ids[0]), int(tracks[1].track_ids[-1])
    assert ids[(1, first)] == ids[(1, second)]
    person = true_track_people(tracks[1], tiny.video)[0]
    in_shot0 = int(tiny.tracks[0].track_ids[list(true_track_people(tiny.tracks[0], tiny.video)).index(person)])
    assert ids[(1, first)] == ids[(0, in_shot0)]  # and the chain is the one matched across the cut
    assert evaluate(linked, tiny.video.truth, body)["ids_total"] == 0
    assert evaluate(unlinked, tiny.video.truth, body)["ids_total"] == 1


def test_a_track_never_seen_is_skipped(tiny):
    tracks = split_track(tiny.tracks[0], 0, 2, 3)
    valid = tracks.valid.copy()
    valid[1] = False  # a track the tracker opened and never confirmed
    tracks = dataclasses.replace(tracks, valid=valid)
    assert link_fragments(tracks, world_pelvis(tracks), ReidConfig(), fps=tiny.shots.fps).tolist() == [-1, -1, 0]


def test_walking_velocity_is_the_walk_over_the_last_second():
    from multithumbs.method.identities import walking_velocity

    rng = np.random.default_rng(0)
    t = np.arange(90) / 30.0
    walk = np.stack([0.8 * t, 0.0 * t, -0.6 * t], 1)          # 1 m/s for the last second...
    walk[:60] = walk[60]                                       # ...after two seconds standing
    noisy = walk + rng.normal(0, 0.05, walk.shape)             # fits' roots jitter by centimetres
    frames = np.arange(90)[np.arange(90) % 7 != 3]             # some frames not seen
    np.testing.assert_allclose(walking_velocity(noisy, frames, 30.0, ReidConfig()), [0.8, 0, -0.6], atol=0.1)
    sprint = walk * 4
    np.testing.assert_allclose(np.linalg.norm(walking_velocity(sprint, frames, 30.0, ReidConfig())), 1.5)
    assert not walking_velocity(noisy, frames[:4], 30.0, ReidConfig()).any()  # too little seen to tell
    assert not walking_velocity(noisy, frames, 30.0, ReidConfig(motion_window=0.0)).any()
