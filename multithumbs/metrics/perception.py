"""How well per-shot perception sees the people that are there: detection, 2D keypoints, per-frame bodies.

These score a perception backend's :class:`~multithumbs.types.PersonTracks` of one shot against the true
people of that shot (:func:`multithumbs.perception.oracle.oracle_tracks` gives them for synthetic and
ground-truth data), frame by frame, before any of the method runs:

* **matching**: in every frame, predicted and true people are paired one to one by the Hungarian
  algorithm on the IoU of their boxes, a pair needing IoU ≥ 0.5 (the PASCAL/COCO criterion). A box is
  that of the mesh's silhouette inside the frame (:func:`silhouette_boxes`): amodal to other people, like
  BlazePose's landmark boxes, which cover occluded limbs too, but cut at the frame's edge the way KITTI
  boxes a truncated object, by the part of it that is in the image. (The mesh's projected box clamped to
  the image would also span the sideways reach of legs below the frame, which no image shows);
* **recall** over *eligible* true people (at least ``min_height`` pixels tall in the image, and at
  least half of their silhouette seen: not beyond the frame's edge, not behind someone else),
  **precision** over all predictions, where a prediction paired with a true person who is there but not
  eligible counts neither way;
* **PCK@α**: the share of a paired person's joints within ``α × max(box width, height)`` of the truth,
  over the joints the truth marks visible and the backend reports (confidence > 0);
* **MPJPE / PA-MPJPE** of the paired people's 24 SMPL joints in the camera frame, pelvis-aligned (the
  per-frame convention of HMR-type estimators, which ignore depth).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy.optimize import linear_sum_assignment

from multithumbs.metrics.identity import box_iou

MIN_IOU = 0.5


def match_people(pred_boxes: np.ndarray, pred_valid: np.ndarray, true_boxes: np.ndarray, true_present: np.ndarray,
                 min_iou: float = MIN_IOU) -> np.ndarray:
    """Per-frame one-to-one pairing of true and predicted people by box IoU.

    Args:
        pred_boxes: ``(N, T, 4)``; pred_valid ``(N, T)``.
        true_boxes: ``(P, T, 4)``; true_present ``(P, T)``.
    Returns:
        ``(P, T)`` int: the paired prediction's index, -1 where none.
    """
    p, t = true_present.shape
    out = np.full((p, t), -1, dtype=np.int64)
    for frame in range(t):
        truth = np.flatnonzero(true_present[:, frame])
        pred = np.flatnonzero(pred_valid[:, frame])
        if truth.size == 0 or pred.size == 0:
            continue
        iou = box_iou(true_boxes[truth, frame], pred_boxes[pred, frame])
        rows, cols = linear_sum_assignment(np.where(iou >= min_iou, iou, 0.0), maximize=True)
        for r, c in zip(rows, cols):
            if iou[r, c] >= min_iou:
                out[truth[r], frame] = pred[c]
    return out


def _silhouettes(vertices_cam: np.ndarray, faces: np.ndarray, K: np.ndarray, image_size: tuple[int, int],
                 margin: float):
    """Yield ``(index, canvas)`` per mesh of ``(..., V, 3)``: its silhouette filled on a canvas ``margin``
    image sizes wider on every side than the image. Meshes with a point at or behind the camera are
    skipped."""
    h, w = image_size
    pad = np.round(np.array([margin * w, margin * h])).astype(int)
    size = (h + 2 * pad[1], w + 2 * pad[0])
    flat = vertices_cam.reshape(-1, *vertices_cam.shape[-2:])
    for i, points in enumerate(flat):
        if not np.all(points[:, 2] > 1e-6):
            continue
        uv = points[:, :2] / points[:, 2:] * K[[0, 1], [0, 1]] + K[[0, 1], 2] + pad
        canvas = np.zeros(size, np.uint8)
        cv2.fillPoly(canvas, np.round(uv[faces]).astype(np.int32), 1)
        yield i, canvas


def silhouette_area(vertices_cam: np.ndarray, faces: np.ndarray, K: np.ndarray, image_size: tuple[int, int],
                    margin: float = 1.0) -> np.ndarray:
    """Pixels the mesh would cover if nothing hid it, counted on a canvas ``margin`` image sizes wider
    on every side than the image (so that parts beyond the frame count): ``(..., V, 3)`` to ``(...)``."""
    out = np.zeros(int(np.prod(vertices_cam.shape[:-2])))
    for i, canvas in _silhouettes(vertices_cam, faces, K, image_size, margin):
        out[i] = canvas.sum()
    return out.reshape(vertices_cam.shape[:-2])


def silhouette_boxes(vertices_cam: np.ndarray, faces: np.ndarray, K: np.ndarray,
                     image_size: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Boxes of the meshes' silhouettes inside the frame, nothing else hiding them: ``(..., V, 3)`` to
    ``boxes (..., 4)`` ``x0, y0, x1, y1`` (the outer edges of the pixels covered; the image spans
    ``[-0.5, W - 0.5] x [-0.5, H - 0.5]``) and ``present (...)``, some pixel in the image covered.

    A body cut by the frame's edge is boxed by the part of it in the image, not by the clamped box of all
    of it: a stride below the frame does not widen its box."""
    shape = vertices_cam.shape[:-2]
    boxes = np.zeros((int(np.prod(shape)), 4))
    present = np.zeros(len(boxes), bool)
    for i, canvas in _silhouettes(vertices_cam, faces, K, image_size, 0.0):
        rows, cols = np.flatnonzero(canvas.any(axis=1)), np.flatnonzero(canvas.any(axis=0))
        if rows.size:
            boxes[i] = cols[0] - 0.5, rows[0] - 0.5, cols[-1] + 0.5, rows[-1] + 0.5
            present[i] = True
    return boxes.reshape(*shape, 4), present.reshape(shape)


def eligible_people(true_vertices_cam: np.ndarray, faces: np.ndarray, K: np.ndarray, image_size: tuple[int, int],
                    visible_pixels: np.ndarray, present: np.ndarray, min_height: float = 80.0,
                    min_visible: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
    """True boxes ``(P, T, 4)`` (:func:`silhouette_boxes`) and the ``(P, T)`` people detection must find:
    present, at least ``min_height`` px tall in the image, and with at least ``min_visible`` of their
    silhouette seen (``visible_pixels (P, T)``, the truth's own masks, over :func:`silhouette_area`: the
    frame's edge and other people both hide it)."""
    boxes, in_image = silhouette_boxes(true_vertices_cam, faces, K, image_size)
    area = silhouette_area(true_vertices_cam, faces, K, image_size)
    seen = np.where(area > 0, visible_pixels / np.where(area > 0, area, 1), 0.0)
    eligible = present & in_image & (boxes[..., 3] - boxes[..., 1] >= min_height) & (seen >= min_visible)
    return boxes, eligible


@dataclass(frozen=True)
class DetectionCounts:
    """Detection tallies of one shot (sums over frames)."""

    true_positives: int
    """Eligible true people paired with a prediction."""
    eligible: int
    """Eligible true people."""
    predictions: int
    """Valid predictions."""
    false_positives: int
    """Predictions paired with no true person that is there."""

    @property
    def recall(self) -> float:
        return self.true_positives / self.eligible if self.eligible else float("nan")

    @property
    def precision(self) -> float:
        return 1.0 - self.false_positives / self.predictions if self.predictions else float("nan")


def detection_counts(matched: np.ndarray, eligible: np.ndarray, pred_valid: np.ndarray) -> DetectionCounts:
    """Tallies from :func:`match_people`'s pairing (``(P, T)``), eligibility ``(P, T)``, ``pred_valid (N, T)``."""
    paired_pred = np.zeros_like(pred_valid, dtype=bool)
    people, frames = np.nonzero(matched >= 0)
    paired_pred[matched[people, frames], frames] = True
    return DetectionCounts(int(((matched >= 0) & eligible).sum()), int(eligible.sum()), int(pred_valid.sum()),
                           int((pred_valid & ~paired_pred).sum()))


MISS_KINDS = ("none", "box_off", "taken")
"""Why an eligible person went unpaired (:func:`miss_kinds`)."""

MISS_PLACES = ("before", "between", "after", "never")
"""Where in the person's own paired frames a miss lies (:func:`miss_kinds`)."""


def miss_kinds(matched: np.ndarray, eligible: np.ndarray, true_boxes: np.ndarray, pred_boxes: np.ndarray,
               pred_valid: np.ndarray, min_iou: float = MIN_IOU, near_iou: float = 0.1) -> dict[tuple[str, str], int]:
    """The eligible true person-frames :func:`match_people` left unpaired, counted by why and where.

    Why (:data:`MISS_KINDS`), from the valid prediction whose box overlaps the person's most: ``"none"``,
    no prediction reaches ``near_iou`` (nobody followed them there); ``"box_off"``, the best is below
    ``min_iou`` (a track is on them, but its box is not); ``"taken"``, it reaches ``min_iou`` but is
    paired with someone else (one track on two overlapping people). Where (:data:`MISS_PLACES`): before
    the person's first paired frame, between two, after the last, or ``"never"`` paired in the shot.

    Args:
        matched: ``(P, T)`` from :func:`match_people`; eligible ``(P, T)``.
        true_boxes: ``(P, T, 4)``; pred_boxes ``(N, T, 4)``; pred_valid ``(N, T)``.
    Returns:
        counts keyed by ``(kind, place)``, every pair present.
    """
    counts = {(kind, place): 0 for kind in MISS_KINDS for place in MISS_PLACES}
    for person, frame in zip(*np.nonzero(eligible & (matched < 0))):
        preds = np.flatnonzero(pred_valid[:, frame])
        iou = box_iou(true_boxes[person, frame][None], pred_boxes[preds, frame])[0] if preds.size else np.zeros(0)
        best = int(np.argmax(iou)) if iou.size else -1
        if best < 0 or iou[best] < near_iou:
            kind = "none"
        elif iou[best] < min_iou:
            kind = "box_off"
        else:
            kind = "taken"
        paired = np.flatnonzero(matched[person] >= 0)
        if not paired.size:
            place = "never"
        else:
            place = "before" if frame < paired[0] else "after" if frame > paired[-1] else "between"
        counts[kind, place] += 1
    return counts


def pck(pred_uv: np.ndarray, true_uv: np.ndarray, joints: np.ndarray, box_size: np.ndarray,
        alpha: float = 0.1) -> tuple[int, int]:
    """Correct and counted keypoints: ``pred_uv, true_uv (..., J, 2)``, ``joints (..., J)`` bool (which
    pairs count), ``box_size (...)`` pixels. Returns ``(correct, counted)``."""
    error = np.linalg.norm(pred_uv - true_uv, axis=-1)
    correct = (error <= alpha * box_size[..., None]) & joints
    return int(correct.sum()), int(joints.sum())


__all__ = ["match_people", "silhouette_area", "silhouette_boxes", "eligible_people", "DetectionCounts",
           "detection_counts", "miss_kinds", "MISS_KINDS", "MISS_PLACES", "pck", "MIN_IOU"]
