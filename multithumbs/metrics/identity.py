"""Identity metric (docs/METRICS.md "IDs"): CLEAR-MOT identity switches, as TrackEval counts them.

Per frame, true people are associated with predictions the way TrackEval's CLEAR metric does
(``trackeval/metrics/clear.py``, the MOTChallenge evaluator): a similarity matrix (2D box IoU, or when
boxes are unavailable TrackEval's Euclidean similarity ``max(0, 1 - d / (2 * max_distance))`` of 3D
roots) plus a bonus of 1000 for the pairs matched at the previous timestep, pairs below the threshold
0.5 removed, then Hungarian. So last frame's correspondences are kept while they stay valid and two
people who overlap for a few frames do not swap. A switch is a true person matched to a predicted
identity different from the last one it was matched to, however long ago. Reported per sequence
(total), per cut (switches whose gap spans that cut) and within shots.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from multithumbs.errors import InputError
from multithumbs.geometry import project


def box_iou(boxes_a: np.ndarray, boxes_b: np.ndarray) -> np.ndarray:
    """Pairwise IoU of boxes ``x0, y0, x1, y1``: ``(..., N, 4)`` and ``(..., M, 4)`` to ``(..., N, M)``.

    Empty boxes (zero or negative extent) have IoU 0 with everything.
    """
    a, b = boxes_a[..., :, None, :], boxes_b[..., None, :, :]
    inter_w = np.clip(np.minimum(a[..., 2], b[..., 2]) - np.maximum(a[..., 0], b[..., 0]), 0, None)
    inter_h = np.clip(np.minimum(a[..., 3], b[..., 3]) - np.maximum(a[..., 1], b[..., 1]), 0, None)
    inter = inter_w * inter_h
    area = lambda box: np.clip(box[..., 2] - box[..., 0], 0, None) * np.clip(box[..., 3] - box[..., 1], 0, None)
    union = area(a) + area(b) - inter
    return np.where(union > 0, inter / np.where(union > 0, union, 1.0), 0.0)


def projected_boxes(points_cam: np.ndarray, K: np.ndarray, image_size: tuple[int, int],
                    min_depth: float = 1e-6) -> tuple[np.ndarray, np.ndarray]:
    """2D boxes of camera-frame point sets (projected meshes), clipped to the image.

    Args:
        points_cam: ``(..., V, 3)`` points in camera coordinates.
        K: ``(..., 3, 3)`` intrinsics.
        image_size: ``(H, W)``; the image spans ``[-0.5, W - 0.5] x [-0.5, H - 0.5]`` (pixel centres
            at integers).
        min_depth: points nearer than this (or behind the camera) are left out.
    Returns:
        ``boxes (..., 4)`` ``x0, y0, x1, y1`` and ``present (...)`` bool: some point is in front of the
        camera and the clipped box has positive area.
    """
    h, w = image_size
    in_front = points_cam[..., 2] > min_depth
    uv = project(points_cam, K)
    lo = np.where(in_front[..., None], uv, np.inf).min(axis=-2)
    hi = np.where(in_front[..., None], uv, -np.inf).max(axis=-2)
    limits = np.array([w - 0.5, h - 0.5])
    lo, hi = np.clip(lo, -0.5, limits), np.clip(hi, -0.5, limits)
    present = in_front.any(axis=-1) & np.all(hi > lo, axis=-1)
    boxes = np.where(present[..., None], np.concatenate([lo, hi], axis=-1), 0.0)
    return boxes, present


SIMILARITY_THRESHOLD = 0.5
"""TrackEval CLEAR's ``THRESHOLD``: a pair needs at least this similarity to match."""

CONTINUATION_BONUS = 1000.0
"""TrackEval CLEAR's weight on last timestep's matches (it exceeds any similarity sum)."""


def clear_mot_match(similarity: np.ndarray, true_present: np.ndarray, pred_present: np.ndarray,
                    threshold: float = SIMILARITY_THRESHOLD) -> np.ndarray:
    """Per-frame CLEAR-MOT association, step for step as TrackEval's ``CLEAR.eval_sequence``.

    At every frame with someone on both sides: score = similarity + 1000 where the pair was matched at
    the previous such frame, zero where the similarity is below ``threshold``; Hungarian maximises the
    score; pairs of zero score stay unmatched. A frame with no true person or no prediction leaves the
    previous matches in place for the next one (TrackEval skips it the same way).

    Args:
        similarity: ``(T, G, P)`` similarity of true person ``g`` and prediction ``p`` at frame ``t``
            (IoU, or another score in ``[0, 1]``).
        true_present: ``(T, G)`` bool.
        pred_present: ``(T, P)`` bool.
        threshold: the similarity a pair needs.
    Returns:
        ``(T, G)`` int index of the matched prediction, -1 when unmatched.
    """
    t_count, g_count, _ = similarity.shape
    eps = np.finfo(np.float64).eps
    matched = np.full((t_count, g_count), -1, dtype=np.int64)
    previous = np.full(g_count, -1, dtype=np.int64)  # match at the previous timestep that had both sides
    for t in range(t_count):
        gts, preds = np.nonzero(true_present[t])[0], np.nonzero(pred_present[t])[0]
        if not len(gts) or not len(preds):
            continue
        sim = similarity[t][np.ix_(gts, preds)]
        score = CONTINUATION_BONUS * (previous[gts][:, None] == preds[None, :]) + sim
        score[sim < threshold - eps] = 0.0
        rows, cols = linear_sum_assignment(-score)
        keep = score[rows, cols] > eps
        previous[:] = -1
        previous[gts[rows[keep]]] = preds[cols[keep]]
        matched[t] = previous
    return matched


def associate_by_iou(true_boxes: np.ndarray, true_present: np.ndarray, pred_boxes: np.ndarray,
                     pred_present: np.ndarray, min_iou: float = SIMILARITY_THRESHOLD) -> np.ndarray:
    """CLEAR-MOT association on box IoU (:func:`clear_mot_match`).

    Args:
        true_boxes: ``(G, T, 4)``.
        true_present: ``(G, T)`` bool.
        pred_boxes: ``(P, T, 4)``.
        pred_present: ``(P, T)`` bool.
        min_iou: pairs need at least this IoU.
    Returns:
        ``(G, T)`` int index of the matched prediction, -1 when unmatched.
    """
    iou = box_iou(true_boxes.transpose(1, 0, 2), pred_boxes.transpose(1, 0, 2))  # (T, G, P)
    return clear_mot_match(iou, true_present.T, pred_present.T, min_iou).T


def associate_by_distance(true_roots: np.ndarray, true_present: np.ndarray, pred_roots: np.ndarray,
                          pred_present: np.ndarray, max_distance: float = 0.5) -> np.ndarray:
    """CLEAR-MOT association on 3D root distance (roots in a common frame, e.g. each frame's camera).

    The similarity is TrackEval's Euclidean one, ``max(0, 1 - d / zero_distance)`` with
    ``zero_distance = 2 * max_distance``, so the 0.5 threshold admits pairs at most ``max_distance``
    apart.

    Args:
        true_roots: ``(G, T, 3)`` metres.
        true_present: ``(G, T)`` bool.
        pred_roots: ``(P, T, 3)``.
        pred_present: ``(P, T)`` bool.
        max_distance: pairs need at most this distance, metres.
    Returns:
        ``(G, T)`` int index of the matched prediction, -1 when unmatched.
    """
    dist = np.linalg.norm(true_roots.transpose(1, 0, 2)[:, :, None] - pred_roots.transpose(1, 0, 2)[:, None],
                          axis=-1)  # (T, G, P)
    similarity = np.clip(1.0 - dist / (2.0 * max_distance), 0.0, None)
    return clear_mot_match(similarity, true_present.T, pred_present.T).T


@dataclass(frozen=True)
class IdSwitches:
    """CLEAR-MOT identity switches of one sequence.

    Attributes:
        switches: ``(G, T)`` bool, true person ``g`` switched identity at frame ``t``.
        spanned_cut: ``(G, T)`` int, for a switch, the index of the last cut between the frame it was
            last matched and this one (the cut the wrong identity came through); -1 for a switch
            within a shot, and wherever there is no switch.
        num_cuts: cuts in the sequence.
    """

    switches: np.ndarray
    spanned_cut: np.ndarray
    num_cuts: int

    @property
    def total(self) -> int:
        return int(self.switches.sum())

    @property
    def per_cut(self) -> float:
        """All switches divided by cuts; NaN for a single-shot sequence."""
        return self.total / self.num_cuts if self.num_cuts else float("nan")

    @property
    def at_cuts(self) -> list[int]:
        """Switches through each cut, in cut order."""
        return [int(((self.spanned_cut == c) & self.switches).sum()) for c in range(self.num_cuts)]

    @property
    def within_shots(self) -> int:
        """Switches whose gap since the last match spans no cut."""
        return int((self.switches & (self.spanned_cut < 0)).sum())

    def events(self, matched: np.ndarray, pred_ids: np.ndarray | None = None) -> list[dict[str, int]]:
        """Every switch as ``{"frame", "true_person", "from_id", "to_id", "last_matched", "cut"}``.

        Args:
            matched: the ``(G, T)`` association the switches were counted from.
            pred_ids: ``(P,)`` global id of every prediction index, as given to :func:`count_id_switches`.
        Returns:
            the switches in frame order; ``cut`` is the index of the cut spanned, -1 within a shot.
        """
        ids = np.arange(int(matched.max(initial=-1)) + 1) if pred_ids is None else np.asarray(pred_ids)
        out = []
        for g, t in sorted(zip(*np.nonzero(self.switches)), key=lambda gt: (gt[1], gt[0])):
            before = np.nonzero(matched[g, :t] >= 0)[0][-1]
            out.append({"frame": int(t), "true_person": int(g), "from_id": int(ids[matched[g, before]]),
                        "to_id": int(ids[matched[g, t]]), "last_matched": int(before),
                        "cut": int(self.spanned_cut[g, t])})
        return out


def count_id_switches(matched: np.ndarray, pred_ids: np.ndarray | None = None,
                      cut_frames: np.ndarray | list[int] = ()) -> IdSwitches:
    """Count CLEAR-MOT switches from a per-frame association.

    Args:
        matched: ``(G, T)`` int index of the matched prediction, -1 when unmatched.
        pred_ids: ``(P,)`` global id of every prediction index; indices are ids when None.
        cut_frames: ``(C,)`` first frame of every new shot.
    Returns:
        the switches.
    """
    if pred_ids is not None and matched.size and matched.max() >= len(pred_ids):
        raise InputError(f"matched: index {matched.max()} out of range for {len(pred_ids)} predicted ids")
    if pred_ids is None:
        ids = matched
    else:
        # -1 marks "unmatched" in a padded lookup table, so an empty prediction needs no special case.
        table = np.append(np.asarray(pred_ids, dtype=np.int64), -1)
        ids = table[np.where(matched >= 0, matched, len(table) - 1)]
    is_matched = matched >= 0
    g, t = matched.shape
    # The last matched frame so far, carried forward over unmatched frames.
    last_index = np.where(is_matched, np.arange(t)[None, :], -1)
    last_index = np.maximum.accumulate(last_index, axis=1)
    previous = np.full((g, t), -1, dtype=np.int64)
    previous[:, 1:] = last_index[:, :-1]
    previous_id = np.take_along_axis(ids, np.clip(previous, 0, None), axis=1)
    switches = is_matched & (previous >= 0) & (previous_id != ids)
    # Cut c lies in the gap (previous, t] when previous < cut_c <= t; the last such cut is the one whose
    # shot the switch happens in.
    cuts = np.sort(np.asarray(cut_frames, dtype=np.int64))
    shot_now = np.searchsorted(cuts, np.arange(t), side="right")[None, :].repeat(g, axis=0)
    shot_before = np.searchsorted(cuts, np.clip(previous, 0, None), side="right")
    spanned = np.where(switches & (shot_now > shot_before), shot_now - 1, -1)
    return IdSwitches(switches, spanned, len(cuts))
