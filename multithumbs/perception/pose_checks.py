"""What the tracker asks of a reading: is it a person, is it the same person as another, how unlike its
track's appearance is it, and where to read that person next. Shared by the forward pass (:mod:`.pose_tracking`) and the backward fill
(:mod:`.backfill`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from multithumbs.perception import blazepose as bp
from multithumbs.perception.shot_assembly import landmark_box
from multithumbs.perception.track_appearance import model_dissimilarity, reading_descriptor

if TYPE_CHECKING:  # annotations only: pose_tracking defines the config and the track
    from multithumbs.perception.pose_tracking import TrackerConfig, _Track


def box_iou(a: np.ndarray, b: np.ndarray) -> float:
    """Intersection over union of two ``(4,)`` boxes."""
    inter = np.prod(np.clip(np.minimum(a[2:], b[2:]) - np.maximum(a[:2], b[:2]), 0, None))
    union = np.prod(a[2:] - a[:2]) + np.prod(b[2:] - b[:2]) - inter
    return float(inter / union) if union > 0 else 0.0


def plausible(found: bp.Landmarks, config: TrackerConfig) -> bool:
    """A pose whose flag is up, whose landmarks span a body-sized part of their square (a landmark set
    shrunk into a corner of it, seen on bodies cut by the frame's edge, is not a person), and whose own
    square is turned at most ``max_roll`` from upright (one read head-down, the face at the hips, would
    give the next frame an upside-down square, and every reading after it is upside down too)."""
    box = landmark_box(found)
    roll = bp.roi_from_landmarks(found).rotation  # already in [-pi, pi)
    return bool(found.presence >= config.min_presence
                and max(box[2] - box[0], box[3] - box[1]) >= config.min_extent * found.roi.size
                and abs(roll) <= config.max_roll)


def same_box(box_a: np.ndarray, box_b: np.ndarray, config: TrackerConfig) -> bool:
    """Two landmark boxes on one person: IoU ≥ ``duplicate_iou``, or one nearly inside the other."""
    inter = np.prod(np.clip(np.minimum(box_a[2:], box_b[2:]) - np.maximum(box_a[:2], box_b[:2]), 0, None))
    smaller = min(np.prod(box_a[2:] - box_a[:2]), np.prod(box_b[2:] - box_b[:2]))
    return bool(box_iou(box_a, box_b) >= config.duplicate_iou or (smaller > 0 and inter / smaller >= config.nested_fraction))


def same_pixels(mask_a: np.ndarray, mask_b: np.ndarray, config: TrackerConfig) -> bool:
    """Two ``(H, W)`` bool segmentations mostly the same pixels (≥ ``mask_overlap`` of the smaller)."""
    fewer = min(mask_a.sum(), mask_b.sum())
    return bool(fewer > 0 and (mask_a & mask_b).sum() / fewer >= config.mask_overlap)


def same_person(a: bp.Landmarks, b: bp.Landmarks, config: TrackerConfig) -> bool:
    """Two poses on one person: their landmark boxes (:func:`same_box`) or their segmentations
    (:func:`same_pixels`: two readings of one body in different squares, as close-ups give) say so."""
    if same_box(landmark_box(a), landmark_box(b), config):
        return True
    return same_pixels(a.segmentation >= config.mask_probability, b.segmentation >= config.mask_probability, config)


def moved_square(reading: bp.Landmarks, earlier: bp.Landmarks | None) -> bp.Roi:
    """The square ``reading``'s landmarks give, moved on by their hips' motion since ``earlier`` (None:
    not moved), damped by half: landmark jitter is not motion. Forwards ``earlier`` is the frame before,
    backwards (:mod:`.backfill`) the frame after."""
    roi = bp.roi_from_landmarks(reading)
    if earlier is None:
        return roi
    step = 0.5 * (reading.image[33, :2] - earlier.image[33, :2])
    return bp.Roi(roi.centre + step, roi.size, roi.rotation)


def describe(frame: np.ndarray, found: bp.Landmarks, config: TrackerConfig) -> np.ndarray:
    """The reading's appearance descriptor (empty with appearance off)."""
    if not config.appearance:
        return np.zeros(0)
    return reading_descriptor(frame, found.segmentation, found.image, config.mask_probability)


def dissimilarity(track: _Track, descriptor: np.ndarray | None, config: TrackerConfig) -> float:
    """How unlike the track's model a reading is; NaN with appearance off or no model yet."""
    if not config.appearance:
        return float("nan")
    return model_dissimilarity(track.model, track.model_counts, descriptor, config.min_model_readings)


__all__ = ["box_iou", "plausible", "same_box", "same_pixels", "same_person", "moved_square", "describe",
           "dissimilarity"]
