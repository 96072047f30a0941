"""Fragments of one person's track joined after the shot: a walker lost for a few frames and found again
where they were heading is one track; a different person, a long gap, a far start or an appearance model
that says otherwise keeps them apart."""

import dataclasses
from types import SimpleNamespace

import numpy as np
import pytest

from multithumbs.perception import track_stitch
from multithumbs.perception.pose_tracking import TrackerConfig, _Track
from multithumbs.perception.track_stitch import predicted_box, stitch_fragments

CONFIG = TrackerConfig()


def _reading(x0: float, y0: float = 50.0, w: float = 40.0, h: float = 120.0) -> SimpleNamespace:
    """A stand-in pose whose 33 landmarks span the box ``x0, y0, x0 + w, y0 + h``."""
    image = np.zeros((39, 5))
    image[:33, 0] = np.linspace(x0, x0 + w, 33)
    image[:33, 1] = np.linspace(y0, y0 + h, 33)
    return SimpleNamespace(image=image)


def _walker(track_id: int, frames, start_x: float = 100.0, speed: float = 5.0, y0: float = 50.0) -> _Track:
    """A track reading someone walking right at ``speed`` px a frame (at ``start_x`` in frame 0)."""
    tr = _Track(track_id)
    for t in frames:
        tr.frames[t] = _reading(start_x + speed * t, y0)
        tr.masks[t] = np.full((4, 1), t, np.uint8)
    return tr


def test_predicted_box_moves_on_at_the_last_velocity():
    tr = _walker(0, range(10))
    np.testing.assert_allclose(predicted_box(tr, 14), [170, 50, 210, 170])
    single = _walker(1, [3])
    np.testing.assert_allclose(predicted_box(single, 9), [115, 50, 155, 170])


def test_a_walker_found_again_where_they_were_heading_is_one_track():
    first, second = _walker(0, range(10)), _walker(1, range(13, 21))
    joined = stitch_fragments([first, second], CONFIG)
    assert [tr.track_id for tr in joined] == [0]
    assert sorted(joined[0].frames) == [*range(10), *range(13, 21)]
    assert joined[0].masks[15][0, 0] == 15  # the later fragment's masks come along


def test_a_fragment_split_off_another_track_brings_its_readings_in_transit_along():
    # s11 shot 2: a split whose square slid onto a man lost 6 frames before continues his track; the
    # readings it took in transit are dropped later from the track it joined (track_split.drop_transit).
    first, second = _walker(0, range(10)), _walker(1, range(13, 21))
    second.transit = {13, 14, 15}
    joined = stitch_fragments([first, second], CONFIG)
    assert len(joined) == 1 and joined[0].transit == {13, 14, 15}


def test_a_chain_of_fragments_joins_in_time_order():
    parts = [_walker(2, range(0, 6)), _walker(0, range(8, 14)), _walker(1, range(16, 22))]
    joined = stitch_fragments(parts, CONFIG)
    assert len(joined) == 1 and joined[0].track_id == 2 and len(joined[0].frames) == 18


@pytest.mark.parametrize("case", ["long gap", "far start", "someone nearer", "overlapping in time", "no gap"])
def test_fragments_that_are_not_one_person_stay_apart(case):
    first = _walker(0, range(10))
    others = []
    if case == "long gap":
        second = _walker(1, range(10 + CONFIG.stitch_gap + 1, 30))
    elif case == "far start":
        second = _walker(1, range(13, 21), start_x=300.0)
    elif case == "someone nearer":
        second = _walker(1, range(13, 21), start_x=120.0)  # 60 px right of where the walker would be
        # Someone followed all along (so no fragment) who is exactly where the walker was heading then.
        others = [_walker(2, range(0, 21), start_x=35.0, speed=10.0)]
    elif case == "overlapping in time":
        second = _walker(1, range(9, 21))
    else:  # starting the frame after: a split, which the appearance models decided
        second = _walker(1, range(10, 21))
    joined = stitch_fragments([first, second, *others], CONFIG)
    assert {tr.track_id for tr in joined} == {0, 1, *(o.track_id for o in others)}
    assert sorted(joined[0].frames) == list(range(10))


def test_an_appearance_model_that_says_someone_else_keeps_them_apart(monkeypatch):
    first, second = _walker(0, range(10)), _walker(1, range(13, 21))
    first.model, first.model_counts, second.model = np.zeros(3), np.zeros(3), np.ones(3)
    monkeypatch.setattr(track_stitch, "model_dissimilarity", lambda *args: CONFIG.drift_dissimilarity + 0.01)
    assert len(stitch_fragments([first, second], CONFIG)) == 2
    monkeypatch.setattr(track_stitch, "model_dissimilarity", lambda *args: CONFIG.drift_dissimilarity)
    assert len(stitch_fragments([first, second], CONFIG)) == 1


def test_off_and_empty_tracks():
    first, second, empty = _walker(0, range(10)), _walker(1, range(13, 21)), _Track(5)
    assert len(stitch_fragments([first, second, empty], dataclasses.replace(CONFIG, stitch_gap=0))) == 2
    assert stitch_fragments([], CONFIG) == []
