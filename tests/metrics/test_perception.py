"""Perception scores: silhouettes and their boxes worked by hand, the per-frame pairing against TrackEval's
CLEAR matching, and the tallies and PCK on hand-counted cases."""

import numpy as np
import pytest

from multithumbs.metrics.identity import projected_boxes
from multithumbs.metrics.perception import (
    MISS_KINDS, MISS_PLACES, detection_counts, eligible_people, match_people, miss_kinds, pck, silhouette_area,
    silhouette_boxes,
)

from tests.metrics.test_identity import _trackeval_similarities

# u = x / z * 100 + 0: a point at depth 1 sits at pixel (100 x, 100 y).
K = np.array([[100.0, 0, 0], [0, 100.0, 0], [0, 0, 1]])
SIZE = (360, 640)


def _at_pixels(uv) -> np.ndarray:
    """Camera-frame points at depth 1 that project onto ``uv (V, 2)``."""
    uv = np.asarray(uv, float)
    return np.concatenate([uv / 100.0, np.ones((len(uv), 1))], axis=1)


def _square(x0, y0, x1, y1) -> tuple[np.ndarray, np.ndarray]:
    """A two-triangle square mesh with corners at those pixel centres."""
    return _at_pixels([(x0, y0), (x1, y0), (x1, y1), (x0, y1)]), np.array([[0, 1, 2], [0, 2, 3]])


def test_box_of_a_body_cut_by_the_frame_is_its_part_in_the_image():
    # A triangle (100,100), (150,100), (400,600) leaves the 360-row image through its bottom edge, y = 359.5.
    # There its edge to (400, 600) is at x = 150 + 250 * 259.5 / 500 = 279.75, its other edge at 255.7:
    # the part in the image spans x 100..279.75, y 100..359.5.
    points, faces = _at_pixels([(100, 100), (150, 100), (400, 600)]), np.array([[0, 1, 2]])
    boxes, present = silhouette_boxes(points, faces, K, SIZE)
    assert present and boxes.shape == (4,)
    np.testing.assert_allclose(boxes, [99.5, 99.5, 280.25, 359.5], atol=1.0)
    clamped, _ = projected_boxes(points, K, SIZE)
    assert clamped[2] == pytest.approx(400.0)  # the clamped box reaches the foot below the frame


def test_box_inside_the_image_matches_the_projected_box_and_shapes_broadcast():
    points, faces = _square(10, 20, 59, 119)
    stacked = np.stack([points, points + [0.3, 0, 0]])[None]  # (1, 2, V, 3); the second is off to the right
    boxes, present = silhouette_boxes(stacked, faces, K, SIZE)
    assert boxes.shape == (1, 2, 4) and present.tolist() == [[True, True]]
    np.testing.assert_allclose(boxes[0, 0], [9.5, 19.5, 59.5, 119.5])
    np.testing.assert_allclose(boxes[0, 0], projected_boxes(points, K, SIZE)[0] + [-0.5, -0.5, 0.5, 0.5])
    np.testing.assert_allclose(boxes[0, 1], [39.5, 19.5, 89.5, 119.5])


def test_mesh_behind_the_camera_or_outside_the_image_has_no_box():
    points, faces = _square(10, 20, 59, 119)
    boxes, present = silhouette_boxes(np.stack([points * [1, 1, -1], _square(700, 20, 760, 119)[0]]), faces, K, SIZE)
    assert present.tolist() == [False, False]
    assert np.all(boxes == 0)


def test_silhouette_area_counts_pixels_beyond_the_frame():
    # 40 x 40 pixel centres, half of them left of the image.
    points, faces = _square(-20, 100, 19, 139)
    assert silhouette_area(points, faces, K, SIZE) == 1600
    assert silhouette_area(points, faces, K, SIZE, margin=0.0) == 800


def test_eligible_people_height_and_share_seen():
    tall, faces = _square(100, 100, 139, 199)  # 100 rows, 4000 pixels
    short, _ = _square(300, 100, 339, 178)  # 79 rows
    vertices = np.stack([tall, tall, short])[:, None]  # (P=3, T=1, V, 3)
    visible = np.array([[2000], [1999], [3160]])  # half seen, just under half, all seen
    boxes, eligible = eligible_people(vertices, faces, K, SIZE, visible, np.ones((3, 1), bool))
    assert boxes.shape == (3, 1, 4)
    assert eligible[:, 0].tolist() == [True, False, False]


def _trackeval_true_positives(true_boxes, true_present, pred_boxes, pred_present) -> int:
    """TrackEval CLEAR's CLR_TP, each frame scored as a sequence of its own (so no continuation bonus)."""
    from trackeval.metrics import CLEAR

    total = 0
    for t in range(true_present.shape[1]):
        data = _trackeval_similarities(true_boxes[:, t:t + 1], true_present[:, t:t + 1], pred_boxes[:, t:t + 1],
                                       pred_present[:, t:t + 1])
        total += int(CLEAR({"PRINT_CONFIG": False}).eval_sequence(data)["CLR_TP"])
    return total


def test_pairing_agrees_with_trackeval_on_random_crowds():
    rng = np.random.default_rng(3)
    p, n, t = 5, 6, 40
    centres = rng.uniform(50, 300, (p, t, 2))
    true_boxes = np.concatenate([centres - 30, centres + 30], -1)
    pick = rng.integers(0, p, (n, t))
    pred_centres = centres[pick, np.arange(t)] + rng.normal(0, 12, (n, t, 2))
    pred_boxes = np.concatenate([pred_centres - 30, pred_centres + 30], -1)
    true_present, pred_valid = rng.random((p, t)) < 0.8, rng.random((n, t)) < 0.7
    matched = match_people(pred_boxes, pred_valid, true_boxes, true_present)
    assert matched.shape == (p, t)
    assert not np.any((matched >= 0) & ~true_present)
    assert int((matched >= 0).sum()) == _trackeval_true_positives(true_boxes, true_present, pred_boxes, pred_valid)


def test_counts_by_hand():
    # Frame 0: person 0 (eligible) found by prediction 0, person 1 (there, not eligible) found by prediction 1,
    # prediction 2 on nobody. Frame 1: person 0 missed, prediction 1 on nobody.
    true_boxes = np.array([[[0, 0, 10, 10], [0, 0, 10, 10]], [[20, 0, 30, 10], [20, 0, 30, 10]]], float)
    pred_boxes = np.array([[[0, 0, 10, 9], [0, 0, 0, 0]], [[20, 0, 30, 10], [50, 0, 60, 10]],
                           [[50, 50, 60, 60], [0, 0, 0, 0]]], float)
    present = np.ones((2, 2), bool)
    eligible = np.array([[True, True], [False, False]])
    valid = np.array([[True, False], [True, True], [True, False]])
    matched = match_people(pred_boxes, valid, true_boxes, present)
    assert matched.tolist() == [[0, -1], [1, -1]]
    counts = detection_counts(matched, eligible, valid)
    assert (counts.true_positives, counts.eligible, counts.predictions, counts.false_positives) == (1, 2, 4, 2)
    assert counts.recall == 0.5 and counts.precision == 0.5


def test_misses_by_hand():
    # Two people over five frames, one prediction. Person 0 is paired at frames 1 and 3 only. At frame 0
    # the prediction is on person 1 (who is paired there) and covers person 0 too: taken, before. At frame 2
    # the prediction sits half off person 0 (IoU 1/3): box off, between. At frame 4 it is gone: none, after.
    # Person 1 is paired at frame 0 and not eligible after it.
    box = np.array([0, 0, 10, 10], float)
    true_boxes = np.stack([np.tile(box, (5, 1)), np.tile(box + [1, 0, 1, 0], (5, 1))])
    pred_boxes = np.tile(box, (1, 5, 1))
    pred_boxes[0, 0] = box + [1, 0, 1, 0]
    pred_boxes[0, 2] = box + [5, 0, 5, 0]
    valid = np.array([[True, True, True, True, False]])
    eligible = np.array([[True] * 5, [True, False, False, False, False]])
    matched = match_people(pred_boxes, valid, true_boxes, np.ones((2, 5), bool))
    assert matched.tolist() == [[-1, 0, -1, 0, -1], [0, -1, -1, -1, -1]]
    counts = miss_kinds(matched, eligible, true_boxes, pred_boxes, valid)
    assert {k: v for k, v in counts.items() if v} == {("taken", "before"): 1, ("box_off", "between"): 1,
                                                      ("none", "after"): 1}
    assert len(counts) == len(MISS_KINDS) * len(MISS_PLACES)
    # Nobody paired in the shot: "never"; the total is the number of misses.
    counts = miss_kinds(np.full((2, 5), -1), eligible, true_boxes, pred_boxes, np.zeros((1, 5), bool))
    assert counts[("none", "never")] == int(eligible.sum()) == sum(counts.values())


def test_pck_by_hand():
    true = np.zeros((1, 3, 2))
    pred = np.array([[[0, 9.9], [10.1, 0], [3, 4]]])  # 9.9, 10.1 and 5 px off
    joints = np.array([[True, True, False]])
    assert pck(pred, true, joints, np.array([100.0])) == (1, 2)
    assert pck(pred, true, np.ones((1, 3), bool), np.array([100.0]), alpha=0.05) == (1, 3)
