"""IDs against the field's CLEAR-MOT evaluators: TrackEval (the reference) and py-motmetrics."""

import numpy as np
import pytest

from multithumbs.errors import InputError
from multithumbs.geometry import intrinsics
from multithumbs.metrics.identity import (
    associate_by_distance, associate_by_iou, box_iou, clear_mot_match, count_id_switches, projected_boxes,
)

# The references are installed by scripts/setup.sh; a missing one fails here rather than skipping.
import motmetrics  # noqa: F401,E402
import trackeval  # noqa: F401,E402


def _trackeval_similarities(true_boxes, true_present, pred_boxes, pred_present, metric="iou"):
    """Per-frame TrackEval input: present ids and TrackEval's own similarity of their boxes (roots)."""
    from trackeval.datasets._base_dataset import _BaseDataset

    data = {"gt_ids": [], "tracker_ids": [], "similarity_scores": []}
    for t in range(true_present.shape[1]):
        gts, preds = np.nonzero(true_present[:, t])[0], np.nonzero(pred_present[:, t])[0]
        if metric == "iou":
            sim = _BaseDataset._calculate_box_ious(true_boxes[gts, t], pred_boxes[preds, t], box_format="x0y0x1y1")
        else:
            sim = _BaseDataset._calculate_euclidean_similarity(true_boxes[gts, t], pred_boxes[preds, t],
                                                               zero_distance=1.0)
        data["gt_ids"].append(gts)
        data["tracker_ids"].append(preds)
        data["similarity_scores"].append(sim)
    data.update(num_timesteps=true_present.shape[1], num_gt_ids=true_present.shape[0],
                num_tracker_ids=pred_present.shape[0], num_gt_dets=int(true_present.sum()),
                num_tracker_dets=int(pred_present.sum()))
    return data


def trackeval_idsw(true_boxes, true_present, pred_boxes, pred_present, metric="iou") -> int:
    """TrackEval's CLEAR IDSW (``trackeval/metrics/clear.py``) on the same per-frame boxes."""
    from trackeval.metrics import CLEAR

    data = _trackeval_similarities(true_boxes, true_present, pred_boxes, pred_present, metric)
    return int(CLEAR({"PRINT_CONFIG": False}).eval_sequence(data)["IDSW"])


def motmetrics_switches(true_boxes, true_present, pred_boxes, pred_present) -> int:
    """py-motmetrics' ``num_switches`` with IoU >= 0.5 as the match gate.

    Distances are 1 - IoU from TrackEval's IoU (NaN below 0.5): motmetrics 1.4.0's own ``iou_matrix``
    calls ``np.asfarray``, which numpy 2 removed; its accumulator works.
    """
    import motmetrics as mm

    data = _trackeval_similarities(true_boxes, true_present, pred_boxes, pred_present)
    acc = mm.MOTAccumulator(auto_id=True)
    for gts, preds, iou in zip(data["gt_ids"], data["tracker_ids"], data["similarity_scores"]):
        acc.update(list(gts), list(preds), np.where(iou >= 0.5, 1.0 - iou, np.nan))
    summary = mm.metrics.create().compute(acc, metrics=["num_switches"], name="s")
    return int(summary["num_switches"].iloc[0])


def ours(true_boxes, true_present, pred_boxes, pred_present, cut_frames=()):
    matched = associate_by_iou(true_boxes, true_present, pred_boxes, pred_present)
    return count_id_switches(matched, cut_frames=cut_frames)


def _box(x, y=0.0, w=10.0, h=20.0):
    return [x, y, x + w, y + h]


def _walk(xs):
    """``(T,)`` x positions to ``(T, 4)`` boxes."""
    return np.array([_box(x) for x in xs], dtype=float)


def _check_all(true_boxes, true_present, pred_boxes, pred_present, expected, motmetrics_agrees=True):
    switches = ours(true_boxes, true_present, pred_boxes, pred_present)
    assert switches.total == expected
    assert trackeval_idsw(true_boxes, true_present, pred_boxes, pred_present) == expected
    if motmetrics_agrees:
        assert motmetrics_switches(true_boxes, true_present, pred_boxes, pred_present) == expected
    return switches


def test_box_iou_hand_computed():
    a = np.array([[0.0, 0.0, 2.0, 2.0]])
    b = np.array([[1.0, 1.0, 3.0, 3.0], [5.0, 5.0, 6.0, 6.0], [0.0, 0.0, 2.0, 2.0], [1.0, 1.0, 1.0, 3.0]])
    np.testing.assert_allclose(box_iou(a, b), [[1 / 7, 0.0, 1.0, 0.0]])


def test_overlapping_people_keep_their_ids():
    # For two frames both people overlap and a fresh Hungarian would swap them (IoU A-b 0.961 > A-a
    # 0.942): CLEAR-MOT keeps last frame's valid matches, so nothing switches.
    t = 10
    true = np.stack([_walk([0.0] * t), _walk([30.0] * 4 + [0.5, 0.5] + [30.0] * 4)])
    pred = np.stack([_walk([0.0] * 4 + [0.3, 0.3] + [0.0] * 4), _walk([30.0] * 4 + [0.2, 0.2] + [30.0] * 4)])
    present = np.ones((2, t), bool)
    assert box_iou(true[:1, 4], pred[:, 4])[0].tolist() == pytest.approx([9.7 / 10.3, 9.8 / 10.2])
    _check_all(true, present, pred, present, expected=0)


def test_crossing_people_do_not_switch():
    t = 21
    xs = np.linspace(0.0, 40.0, t)
    true = np.stack([_walk(xs), _walk(xs[::-1])])
    pred = true + np.array([0.5, 0.0, 0.5, 0.0])
    present = np.ones((2, t), bool)
    _check_all(true, present, pred, present, expected=0)


def test_a_duplicate_track_is_not_a_switch():
    t = 12
    true = _walk(np.arange(t, dtype=float))[None]
    pred = np.stack([true[0] + 0.2, true[0] - 0.2])  # the duplicate shows up from frame 4 on
    pred_present = np.array([[True] * t, [False] * 4 + [True] * (t - 4)])
    _check_all(true, np.ones((1, t), bool), pred, pred_present, expected=0)


def test_a_lost_track_coming_back():
    t = 16
    true = _walk(np.arange(t, dtype=float))[None]
    present = np.ones((1, t), bool)
    # Lost for frames 6-9, then back with the same id: no switch.
    pred = true.copy()
    gone = present.copy()
    gone[0, 6:10] = False
    _check_all(true, present, pred, gone, expected=0)
    # Back under a new id: one switch, however long the gap.
    pred2 = np.concatenate([pred, pred])
    pred2_present = np.stack([np.arange(t) < 6, np.arange(t) >= 10])
    switches = _check_all(true, present, pred2, pred2_present, expected=1)
    assert switches.switches[0, 10]


def test_real_swaps_at_a_cut_count_and_are_attributed_to_the_cut():
    t, cut = 12, 6
    true = np.stack([_walk([0.0] * t), _walk([50.0] * t)])
    pred = np.stack([_walk([0.0] * cut + [50.0] * (t - cut)), _walk([50.0] * cut + [0.0] * (t - cut))])
    present = np.ones((2, t), bool)
    switches = _check_all(true, present, pred, present, expected=2)
    switches = ours(true, present, pred, present, cut_frames=[3, cut])
    assert switches.at_cuts == [0, 2] and switches.within_shots == 0
    assert switches.per_cut == pytest.approx(1.0)


def test_a_switch_inside_a_shot_is_within_shots():
    t = 10
    true = np.stack([_walk([0.0] * t), _walk([50.0] * t)])
    pred = np.stack([_walk([0.0] * 3 + [50.0] * 7), _walk([50.0] * 3 + [0.0] * 7)])
    present = np.ones((2, t), bool)
    switches = ours(true, present, pred, present, cut_frames=[6])
    assert switches.total == 2 and switches.within_shots == 2 and switches.at_cuts == [0]


def _random_scene(rng, t=60, people=3):
    """People walking in 1D with random overlaps; predictions jittered, some dropped, duplicated,
    swapped, some positions scaled x1.5 about the image centre (a wrongly scaled trajectory)."""
    starts = rng.uniform(0, 60, people)
    speeds = rng.normal(0, 1.0, people)
    xs = starts[:, None] + speeds[:, None] * np.arange(t)[None]
    true = np.stack([_walk(x) for x in xs])
    true_present = rng.random((people, t)) > 0.1
    pred = np.concatenate([true + rng.normal(0, 1.0, true.shape), true[:1] + rng.normal(0, 1.0, true[:1].shape)])
    if rng.random() < 0.5:
        pred[:, :, [0, 2]] = 30.0 + 1.5 * (pred[:, :, [0, 2]] - 30.0)
    swap_at = int(rng.integers(5, t - 5))
    pred[[0, 1], swap_at:] = pred[[1, 0], swap_at:]
    pred_present = np.concatenate([rng.random((people, t)) > 0.15, rng.random((1, t)) > 0.7])
    return true, true_present, pred, pred_present


@pytest.mark.parametrize("seed", range(20))
def test_random_scenes_equal_trackeval(seed):
    rng = np.random.default_rng(seed)
    true, true_present, pred, pred_present = _random_scene(rng)
    assert ours(true, true_present, pred, pred_present).total == \
        trackeval_idsw(true, true_present, pred, pred_present)


@pytest.mark.parametrize("seed", range(5))
def test_root_distance_association_equals_trackeval_euclidean(seed):
    rng = np.random.default_rng(100 + seed)
    t, people = 40, 3
    true = np.cumsum(rng.normal(0, 0.15, (people, t, 3)), axis=1)
    pred = true + rng.normal(0, 0.2, true.shape)
    pred[[0, 1], 20:] = pred[[1, 0], 20:]
    present = rng.random((people, t)) > 0.1
    pred_present = rng.random((people, t)) > 0.1
    matched = associate_by_distance(true, present, pred, pred_present, max_distance=0.5)
    expected = trackeval_idsw(true, present, pred, pred_present, metric="euclidean")
    assert count_id_switches(matched).total == expected


def test_clear_mot_match_keeps_the_previous_match_over_a_better_one():
    similarity = np.array([[[0.9, 0.6]], [[0.6, 0.9]]])
    present = np.ones((2, 1), bool)
    assert clear_mot_match(similarity, present, np.ones((2, 2), bool)).tolist() == [[0], [0]]
    # Below the threshold the previous match is not valid any more.
    similarity[1, 0, 0] = 0.4
    assert clear_mot_match(similarity, present, np.ones((2, 2), bool)).tolist() == [[0], [1]]


def test_count_id_switches_hand_computed():
    matched = np.array([
        [0, 0, -1, 1, 1, 0],     # 0 -> 1 at t=3, 1 -> 0 at t=5: two switches
        [2, -1, -1, -1, -1, 2],  # back to the same id after a long gap: none
        [-1, -1, 2, -1, -1, 3],  # 2 -> 3 however long ago: one
    ])
    switches = count_id_switches(matched, cut_frames=[2, 4])
    assert switches.total == 3
    np.testing.assert_array_equal(np.argwhere(switches.switches), [[0, 3], [0, 5], [2, 5]])
    assert switches.per_cut == pytest.approx(1.5)
    # (0, 3): last matched at 1, cut 2 between; (0, 5): last at 4, none; (2, 5): last at 2, cut 4.
    assert switches.at_cuts == [1, 1] and switches.within_shots == 1
    assert np.isnan(count_id_switches(matched).per_cut)
    assert switches.events(matched) == [
        {"frame": 3, "true_person": 0, "from_id": 0, "to_id": 1, "last_matched": 1, "cut": 0},
        {"frame": 5, "true_person": 0, "from_id": 1, "to_id": 0, "last_matched": 4, "cut": -1},
        {"frame": 5, "true_person": 2, "from_id": 2, "to_id": 3, "last_matched": 2, "cut": 1},
    ]


def test_count_id_switches_uses_global_ids():
    # Indices 0 and 1 carry the same global id: no switch.
    matched = np.array([[0, 0, 1, 1]])
    assert count_id_switches(matched, pred_ids=np.array([7, 7])).total == 0
    assert count_id_switches(matched, pred_ids=np.array([7, 8])).total == 1
    with pytest.raises(InputError, match="matched"):
        count_id_switches(matched, pred_ids=np.array([7]))


def test_iou_threshold_leaves_poor_overlaps_unmatched():
    true_boxes = np.array([[_box(0, 0)]])
    pred_boxes = np.array([[_box(4, 0)]])  # IoU = 6 / 14 < 0.5
    matched = associate_by_iou(true_boxes, np.ones((1, 1), bool), pred_boxes, np.ones((1, 1), bool))
    assert matched.tolist() == [[-1]]
    looser = associate_by_iou(true_boxes, np.ones((1, 1), bool), pred_boxes, np.ones((1, 1), bool), min_iou=0.4)
    assert looser.tolist() == [[0]]


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
