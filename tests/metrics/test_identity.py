import numpy as np
import pytest

from multithumbs.errors import InputError
from multithumbs.geometry import intrinsics
from multithumbs.metrics.identity import (
    associate_by_distance, associate_by_iou, box_iou, count_id_switches, match_frames, projected_boxes,
)


def test_box_iou_hand_computed():
    a = np.array([[0.0, 0.0, 2.0, 2.0]])
    b = np.array([[1.0, 1.0, 3.0, 3.0], [5.0, 5.0, 6.0, 6.0], [0.0, 0.0, 2.0, 2.0], [1.0, 1.0, 1.0, 3.0]])
    np.testing.assert_allclose(box_iou(a, b), [[1 / 7, 0.0, 1.0, 0.0]])


def test_count_id_switches_hand_computed():
    matched = np.array([
        [0, 0, -1, 1, 1, 0],     # 0 -> 1 at t=3, 1 -> 0 at t=5: two switches
        [2, -1, -1, -1, -1, 2],  # back to the same id after a long gap: none
        [-1, -1, 2, -1, -1, 3],  # 2 -> 3 however long ago: one
    ])
    switches = count_id_switches(matched, num_cuts=2)
    assert switches.total == 3
    np.testing.assert_array_equal(np.argwhere(switches.switches), [[0, 3], [0, 5], [2, 5]])
    assert switches.per_cut == pytest.approx(1.5)
    assert np.isnan(count_id_switches(matched, num_cuts=0).per_cut)


def test_count_id_switches_uses_global_ids():
    # Indices 0 and 1 carry the same global id: no switch.
    matched = np.array([[0, 0, 1, 1]])
    assert count_id_switches(matched, pred_ids=np.array([7, 7])).total == 0
    assert count_id_switches(matched, pred_ids=np.array([7, 8])).total == 1
    with pytest.raises(InputError, match="matched"):
        count_id_switches(matched, pred_ids=np.array([7]))


def _box(x, y, w=10.0, h=20.0):
    return [x, y, x + w, y + h]


def test_one_swapped_id_at_a_cut_is_one_switch():
    t, cut = 6, 3
    true_boxes = np.array([[_box(0, 0)] * t, [_box(100, 0)] * t])
    # Prediction 0 follows true 0 before the cut, prediction 2 after it; prediction 1 follows true 1.
    pred_boxes = np.array([[_box(1, 0)] * t, [_box(101, 1)] * t, [_box(0, 1)] * t])
    pred_present = np.array([[True] * cut + [False] * (t - cut), [True] * t, [False] * cut + [True] * (t - cut)])
    matched = associate_by_iou(true_boxes, np.ones((2, t), bool), pred_boxes, pred_present)
    np.testing.assert_array_equal(matched, [[0, 0, 0, 2, 2, 2], [1] * t])
    switches = count_id_switches(matched, pred_ids=np.array([10, 11, 12]), num_cuts=1)
    assert switches.total == 1 and switches.switches[0, cut]


def test_iou_threshold_leaves_poor_overlaps_unmatched():
    true_boxes = np.array([[_box(0, 0)]])
    pred_boxes = np.array([[_box(4, 0)]])  # IoU = 6 / 14 < 0.5
    matched = associate_by_iou(true_boxes, np.ones((1, 1), bool), pred_boxes, np.ones((1, 1), bool))
    assert matched.tolist() == [[-1]]
    looser = associate_by_iou(true_boxes, np.ones((1, 1), bool), pred_boxes, np.ones((1, 1), bool), min_iou=0.4)
    assert looser.tolist() == [[0]]


def test_match_frames_is_optimal_not_greedy():
    # Greedy would pair (0, 0) at cost 1 and leave (1, 1) at cost 10; Hungarian picks 2 + 2.
    cost = np.array([[[1.0, 2.0], [2.0, 10.0]]])
    assert match_frames(cost, np.ones_like(cost, dtype=bool)).tolist() == [[1, 0]]
    allowed = np.array([[[True, False], [True, False]]])
    assert match_frames(cost, allowed).tolist() == [[0, -1]]


def test_associate_by_distance_threshold():
    true_roots = np.array([[[0.0, 0.0, 3.0], [0.0, 0.0, 3.0]]])
    pred_roots = np.array([[[0.4, 0.0, 3.0], [0.6, 0.0, 3.0]]])
    both = np.ones((1, 2), bool)
    assert associate_by_distance(true_roots, both, pred_roots, both).tolist() == [[0, -1]]


def test_projected_boxes_clip_and_skip_points_behind():
    K = intrinsics(100.0, 100.0, 50.0, 40.0)
    points = np.array([[[0.0, 0.0, 1.0], [0.2, 0.1, 1.0], [5.0, 0.0, -1.0]],   # third point behind
                       [[-2.0, -2.0, 1.0], [0.0, 0.0, 1.0], [0.0, 0.0, 2.0]],  # clipped at the corner
                       [[0.0, 0.0, -1.0], [0.1, 0.0, -2.0], [0.0, 0.1, -1.0]]])  # all behind
    boxes, present = projected_boxes(points, K, (80, 100))
    assert present.tolist() == [True, True, False]
    np.testing.assert_allclose(boxes[0], [50.0, 40.0, 70.0, 50.0])
    np.testing.assert_allclose(boxes[1], [-0.5, -0.5, 50.0, 40.0])
