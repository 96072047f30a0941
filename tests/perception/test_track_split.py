"""The typical fit a track's split is judged against (:func:`track_split.remember_fit`), and which lost track
a person found again continues (``pose_tracking._lost_track_for``), on the numbers the standard suite's s02
gave from its pixels (docs/RESULTS.md, session 18)."""

import dataclasses

import numpy as np

from multithumbs.perception import blazepose as bp
from multithumbs.perception import pose_tracking, track_split
from multithumbs.perception.pose_tracking import TrackerConfig, _lost_track_for, _Track
from multithumbs.perception.track_split import drop_transit, merged_back, moved, remember_fit, split

SLIDE = (0.10, 0.12, 0.21, 0.14, 0.12, 0.285, 0.255)
"""s02's track 1, frames 32-38: its usual fits, then two readings a little worse as its square slid onto
the person beside it (the readings after them were 0.45-0.49 unlike its model)."""


def test_a_square_sliding_onto_someone_does_not_raise_the_typical_fit():
    config = TrackerConfig()
    track = _Track(1)
    for fit in SLIDE:
        remember_fit(track, fit, config)
    assert track.fits == [0.10, 0.12, 0.21, 0.14, 0.12]
    track.unlike = [39, 40, 41]
    assert moved(track, config)
    # Taken in as they came, the two slid readings raise the median to 0.21, and the track is not split.
    before = _Track(1, fits=list(SLIDE[-5:]), unlike=[39, 40, 41])
    assert not moved(before, config)


def test_remember_fit_keeps_the_last_five_usual_fits_and_skips_nan():
    config = TrackerConfig()
    track = _Track(1)
    for fit in (float("nan"), 0.05, 0.06, 0.07, 0.08, 0.09, 0.10, float("nan"), 0.16):
        remember_fit(track, fit, config)
    assert track.fits == [0.07, 0.08, 0.09, 0.10, 0.16]  # 0.16 is 0.08 above the median 0.08: usual
    remember_fit(track, 0.22, config)  # 0.13 above the median 0.09
    assert track.fits == [0.07, 0.08, 0.09, 0.10, 0.16]


def _landmarks(box: tuple[float, float, float, float]) -> bp.Landmarks:
    image = np.zeros((39, 5))
    image[:33, 0] = np.linspace(box[0], box[2], 33)
    image[:33, 1] = np.linspace(box[1], box[3], 33)
    return bp.Landmarks(1.0, image, np.zeros((33, 3)), np.zeros((1, 1), np.float32), None)


def test_a_model_that_finds_the_person_unlike_its_own_does_not_take_them_from_a_closer_track(monkeypatch):
    config = TrackerConfig()
    # both lost 5 frames ago; the person found again overlaps the first by 0.33 and the second exactly
    modelled = _Track(1, last=_landmarks((100, 100, 200, 300)), missed=5)
    unmodelled = _Track(2, last=_landmarks((150, 100, 250, 300)), missed=5)
    fits = {1: 0.48, 2: float("nan")}  # s02 frame 48: a model 0.48 unlike, a track too young for one
    monkeypatch.setattr(pose_tracking, "dissimilarity", lambda track, descriptor, config: fits[track.track_id])
    box = np.array([150.0, 100.0, 250.0, 300.0])
    assert _lost_track_for(box, np.zeros(3), [modelled, unmodelled], config) is unmodelled
    fits[1] = 0.1  # a model that finds the person like its own still takes them
    assert _lost_track_for(box, np.zeros(3), [modelled, unmodelled], config) is modelled


def _followed(track_id: int, frames) -> _Track:
    """A track with a reading and a mask in each of ``frames`` (boxes along a line; their place is not asked)."""
    track = _Track(track_id)
    for t in frames:
        track.frames[t] = _landmarks((10.0 * t, 0.0, 10.0 * t + 40, 120.0))
        track.masks[t] = np.full((2, 1), t, np.uint8)
    return track


def _split_at(parent: _Track, streak: list[int]) -> tuple[_Track, list[_Track]]:
    tracks = [parent]
    parent.unlike = list(streak)
    child = split(parent, streak[-1], tracks, lambda: _Track(len(tracks)))
    return child, tracks


def test_a_split_that_stands_loses_the_readings_of_its_square_in_transit():
    # s11 shot 2: the square slid from one person onto another over the 3 frames of the streak.
    parent = _followed(0, range(10))
    child, _ = _split_at(parent, [7, 8, 9])
    assert sorted(parent.frames) == list(range(7)) and sorted(child.frames) == [7, 8, 9]
    for t in (10, 11, 12):  # the child carries on, on its new person
        child.frames[t] = _landmarks((10.0 * t, 0.0, 10.0 * t + 40, 120.0))
        child.masks[t] = np.zeros((2, 1), np.uint8)
    drop_transit(child, TrackerConfig())
    assert sorted(child.frames) == [10, 11, 12] and sorted(child.masks) == [10, 11, 12]
    drop_transit(parent, TrackerConfig())
    assert sorted(parent.frames) == list(range(7))


def test_transit_readings_are_kept_when_asked():
    child, _ = _split_at(_followed(0, range(10)), [7, 8, 9])
    drop_transit(child, dataclasses.replace(TrackerConfig(), drop_transit=False))
    assert sorted(child.frames) == [7, 8, 9]


def test_a_split_merged_back_keeps_every_reading_under_the_old_id(monkeypatch):
    # Its own person read poorly: the streak was theirs, not a square in transit.
    config = TrackerConfig()
    parent = _followed(0, range(10))
    child, _ = _split_at(parent, [7, 8, 9])
    monkeypatch.setattr(track_split, "dissimilarity", lambda track, descriptor, config: 0.05)
    horizon = config.max_missed
    for t in (10, 11, 12):
        parent.missed += 1
        child.frames[t] = _landmarks((10.0 * t, 0.0, 10.0 * t + 40, 120.0))
        merged = merged_back(child, np.zeros(3), config, horizon)
    assert merged and sorted(parent.frames) == list(range(13))
    drop_transit(parent, config)
    drop_transit(child, config)
    assert sorted(parent.frames) == list(range(13)) and not child.frames

