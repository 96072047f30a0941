"""Identity metric (METRICS.md "IDs"): CLEAR-MOT identity switches.

Per frame, true people are associated with predictions by Hungarian on 2D box IoU (pairs need
IoU >= 0.5) or, when boxes are unavailable, on 3D root distance (pairs need <= 0.5 m). A switch is a
true person matched to a predicted identity different from the last one it was matched to, however
long ago. Reported per sequence (total) and per cut.
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


def match_frames(cost: np.ndarray, allowed: np.ndarray) -> np.ndarray:
    """Per-frame Hungarian association restricted to allowed pairs.

    Args:
        cost: ``(T, G, P)`` cost of pairing true person ``g`` with prediction ``p`` at frame ``t``.
        allowed: ``(T, G, P)`` bool, the pair may be matched (presence and threshold).
    Returns:
        ``(T, G)`` int index of the matched prediction, -1 when unmatched.
    """
    t_count, g_count, _ = cost.shape
    matched = np.full((t_count, g_count), -1, dtype=np.int64)
    for t in np.nonzero(allowed.any(axis=(1, 2)))[0]:
        ok = allowed[t]
        real = cost[t][ok]
        # A forbidden pair costs more than all allowed pairs together, so Hungarian maximises the
        # number of allowed matches first; forbidden pairs it still returns are dropped.
        penalty = np.abs(real).sum() + 1.0
        rows, cols = linear_sum_assignment(np.where(ok, cost[t], penalty))
        keep = ok[rows, cols]
        matched[t, rows[keep]] = cols[keep]
    return matched


def associate_by_iou(true_boxes: np.ndarray, true_present: np.ndarray, pred_boxes: np.ndarray,
                     pred_present: np.ndarray, min_iou: float = 0.5) -> np.ndarray:
    """Per-frame association on box IoU.

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
    allowed = true_present.T[:, :, None] & pred_present.T[:, None, :] & (iou >= min_iou)
    return match_frames(-iou, allowed).T


def associate_by_distance(true_roots: np.ndarray, true_present: np.ndarray, pred_roots: np.ndarray,
                          pred_present: np.ndarray, max_distance: float = 0.5) -> np.ndarray:
    """Per-frame association on 3D root distance (roots in a common frame, e.g. each frame's camera).

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
    allowed = true_present.T[:, :, None] & pred_present.T[:, None, :] & (dist <= max_distance)
    return match_frames(dist, allowed).T


@dataclass(frozen=True)
class IdSwitches:
    """CLEAR-MOT identity switches of one sequence.

    Attributes:
        switches: ``(G, T)`` bool, true person ``g`` switched identity at frame ``t``.
        num_cuts: cuts in the sequence (for the per-cut figure).
    """

    switches: np.ndarray
    num_cuts: int

    @property
    def total(self) -> int:
        return int(self.switches.sum())

    @property
    def per_cut(self) -> float:
        """Switches divided by cuts; NaN for a single-shot sequence."""
        return self.total / self.num_cuts if self.num_cuts else float("nan")


def count_id_switches(matched: np.ndarray, pred_ids: np.ndarray | None = None, num_cuts: int = 0) -> IdSwitches:
    """Count CLEAR-MOT switches from a per-frame association.

    Args:
        matched: ``(G, T)`` int index of the matched prediction, -1 when unmatched.
        pred_ids: ``(P,)`` global id of every prediction index; indices are ids when None.
        num_cuts: cuts in the sequence.
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
    # The last matched id so far, carried forward over unmatched frames.
    last_index = np.where(is_matched, np.arange(t)[None, :], -1)
    last_index = np.maximum.accumulate(last_index, axis=1)
    previous = np.full((g, t), -1, dtype=np.int64)
    previous[:, 1:] = last_index[:, :-1]
    previous_id = np.take_along_axis(ids, np.clip(previous, 0, None), axis=1)
    switches = is_matched & (previous >= 0) & (previous_id != ids)
    return IdSwitches(switches, int(num_cuts))
