"""The tracker's appearance models: their algebra on hand-made descriptors, and their decisions on frames
whose people are coloured boxes (``test_pose_tracking``'s stand-in for BlazePose)."""

import dataclasses

import numpy as np
import pytest

from multithumbs.perception import blazepose as bp
from multithumbs.appearance import DESCRIPTOR_SIZE, HUE_BINS, REGION_SIZE, REGIONS, SAT_BINS
from multithumbs.perception.pose_tracking import TrackerConfig, track_shot
from multithumbs.perception.track_appearance import (clearly_better, model_dissimilarity, reading_descriptor,
                                                     updated_model)

from tests.perception.test_pose_tracking import ColourModel, identity_of, render


def descriptor(cell: int, regions=range(len(REGIONS))) -> np.ndarray:
    """A descriptor whose valid regions put all their pixels in one hue-saturation cell."""
    out = np.zeros((len(REGIONS), REGION_SIZE))
    for r in regions:
        out[r, 0] = 1.0
        out[r, 1 + cell] = 1.0
    return out.reshape(-1)


def test_model_is_a_running_mean_capped_at_its_memory():
    a, b = descriptor(3), descriptor(20)
    model, counts = updated_model(None, None, a, memory=2)
    assert np.array_equal(model, a) and counts.tolist() == [1, 1, 1, 1]
    model, counts = updated_model(model, counts, b, memory=2)       # mean of two
    hist = model.reshape(len(REGIONS), REGION_SIZE)[0, 1:1 + HUE_BINS * SAT_BINS]
    assert hist[3] == pytest.approx(0.5) and hist[20] == pytest.approx(0.5)
    model, counts = updated_model(model, counts, b, memory=2)       # step 1/3, not 1/3 of a longer mean
    hist = model.reshape(len(REGIONS), REGION_SIZE)[0, 1:1 + HUE_BINS * SAT_BINS]
    assert hist[3] == pytest.approx(1 / 3) and counts.tolist() == [3, 3, 3, 3]
    # a region the reading does not describe keeps what it had
    model2, counts2 = updated_model(model, counts, descriptor(0, regions=[1]), memory=2)
    assert np.array_equal(model2.reshape(4, -1)[0], model.reshape(4, -1)[0]) and counts2.tolist() == [3, 4, 3, 3]
    # an empty reading changes nothing
    assert updated_model(model, counts, np.zeros(DESCRIPTOR_SIZE), 2)[0] is model


def test_dissimilarity_needs_enough_readings_and_a_shared_region():
    model, counts = updated_model(None, None, descriptor(5, regions=[0, 1]), memory=20)
    assert np.isnan(model_dissimilarity(None, None, descriptor(5), 1))
    assert np.isnan(model_dissimilarity(model, counts, descriptor(5), min_readings=2))   # one reading
    assert model_dissimilarity(model, counts, descriptor(5), 1) == pytest.approx(0.0)
    assert model_dissimilarity(model, counts, descriptor(30), 1) == pytest.approx(0.5)  # histogram apart, same chroma
    assert np.isnan(model_dissimilarity(model, counts, descriptor(5, regions=[3]), 1))  # nothing shared


def test_clearly_better_needs_the_margin():
    assert clearly_better([0.1, 0.5], 0.2) == 0
    assert clearly_better([0.5, 0.4], 0.2) is None
    assert clearly_better([float("nan"), 0.4], 0.2) == 1
    assert clearly_better([float("nan")] * 2, 0.2) is None
    assert clearly_better([0.3], 0.2) == 0


def test_reading_descriptor_tells_the_box_people_apart():
    frames = render({0: [(100, 120)], 1: [(300, 120)]}, 1)
    model = ColourModel()
    readings = [model.landmarks(frames[0], bp.Roi(np.array([x, 126.0]), 200.0, 0.0)) for x in (100, 300)]
    d = [reading_descriptor(frames[0], r.segmentation, r.image) for r in readings]
    assert d[0].shape == (DESCRIPTOR_SIZE,) and d[0].reshape(4, -1)[:, 0].any()
    own, _ = updated_model(None, None, d[0], 20)
    counts = np.full(len(REGIONS), 5)
    assert model_dissimilarity(own, counts, d[0], 1) < 0.05
    assert model_dissimilarity(own, counts, d[1], 1) > 0.6


def crossing_behind(n: int = 40):
    """Person 0 (found first: track 0) walks right behind person 1, who walks left in front of them; for
    a few frames person 0 is wholly hidden."""
    back = [(60 + 7 * t, 120) for t in range(n)]
    front = [(340 - 7 * t, 120) for t in range(n)]
    return render({0: back, 1: front}, n, order=[0, 1])


def test_a_track_that_slides_onto_the_front_person_is_dropped_not_swapped():
    frames = crossing_behind()
    n = len(frames)
    ids = {}
    for appearance in (False, True):
        poses = track_shot(frames, ColourModel(), TrackerConfig(appearance=appearance))
        ids[appearance] = [{identity_of(poses, frames, k, t) for t in range(n)} - {None} for k in (0, 1)]
    # by boxes alone the hidden person's older track takes the front person over while they are hidden
    assert len(ids[False][1]) == 2
    # by appearance each keeps one id of their own
    assert len(ids[True][0]) == 1 and len(ids[True][1]) == 1 and ids[True][0] != ids[True][1]


def test_a_person_back_after_a_long_gap_is_found_by_appearance():
    n = 60
    a = [(100 + 2 * t, 120) if not 10 <= t < 40 else None for t in range(n)]   # gone 30 frames, back 60 px on
    b = [(320, 120)] * n
    frames = render({0: a, 1: b}, n)
    config = TrackerConfig(max_missed=5)
    with_app = track_shot(frames, ColourModel(), config)
    boxes_only = track_shot(frames, ColourModel(), dataclasses.replace(config, appearance=False))
    assert identity_of(with_app, frames, 0, 5) == identity_of(with_app, frames, 0, 50)
    assert identity_of(boxes_only, frames, 0, 5) != identity_of(boxes_only, frames, 0, 50)
    # a different person entering where the lost one was is not taken for them
    c = [None if t < 40 else (100 + 2 * t, 120) for t in range(n)]
    frames = render({0: a[:40] + [None] * 20, 2: c, 1: b}, n)
    poses = track_shot(frames, ColourModel(), config)
    assert identity_of(poses, frames, 2, 50) is not None
    assert identity_of(poses, frames, 2, 50) != identity_of(poses, frames, 0, 5)
