"""The backward fill at the end of a shot: each track followed back from where it was found.

The detector is anchored on the face, so a person who walks in with their back to the camera, or who is
hidden behind someone, is found frames after they could have been followed: the forward pass of
:mod:`.pose_tracking` has nothing to start from until then. Once the shot is read, every run of a track
(its first frame, and the frame it was found again after a gap) is followed backwards the way the forward
pass follows forwards: frame ``t - 1``'s square comes from frame ``t``'s landmarks, moved on by their last
motion. It stops at the track's previous run, after ``backfill`` frames, or at the first reading that is
not a plausible pose, that fits the track's appearance model poorly (above ``split_dissimilarity``: the
forward pass does not learn from such readings either), or that lands on or near a person already
followed in that frame (box overlap ≥ ``revive_iou``, or :func:`.pose_checks.same_box`, or mostly their
pixels). A filled frame's mask is its segmentation in its square, less the pixels
the frame's other people already own (their masks were settled with the frame).
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING, Sequence

import cv2
import numpy as np

from multithumbs.perception import blazepose as bp
from multithumbs.perception.pose_checks import box_iou, describe, dissimilarity, plausible, same_box, same_pixels
from multithumbs.perception.shot_assembly import landmark_box

if TYPE_CHECKING:  # annotations only: pose_tracking defines the config and the track
    from multithumbs.perception.pose_tracking import TrackerConfig, _Track


def backward_roi(track: _Track, t: int) -> bp.Roi:
    """Frame ``t``'s square for a track read in frame ``t + 1``: that reading's square, moved on by the
    motion from ``t + 2`` to ``t + 1`` (damped, as forwards)."""
    after = track.frames[t + 1]
    roi = bp.roi_from_landmarks(after)
    further = track.frames.get(t + 2)
    if further is None:
        return roi
    step = 0.5 * (after.image[33, :2] - further.image[33, :2])
    return bp.Roi(roi.centre + step, roi.size, roi.rotation)


def _square_mask(found: bp.Landmarks, config: TrackerConfig) -> np.ndarray:
    """``(H, W)`` bool: the reading's segmentation inside the square it came from."""
    region = np.zeros(found.segmentation.shape, np.uint8)
    cv2.fillConvexPoly(region, np.round(found.roi.corners()).astype(np.int32), 1)
    return (found.segmentation >= config.mask_probability) & (region > 0)


def _fill_before(track: _Track, start: int, tracks: list[_Track], frames: Sequence[np.ndarray], model,
                 config: TrackerConfig) -> int:
    """Follow ``track`` back from frame ``start`` (module docstring). Returns the landmark calls made."""
    calls = 0
    t = start - 1
    width = frames[0].shape[1]
    while t >= 0 and t not in track.frames and start - t <= config.backfill:
        found = model.landmarks(frames[t], backward_roi(track, t))
        calls += 1
        if not plausible(found, config):
            break
        if dissimilarity(track, describe(frames[t], found, config), config) > config.split_dissimilarity:
            break  # only readings like the track's person (forwards, those above it are not learnt from)
        others = [tr for tr in tracks if tr is not track and t in tr.frames]
        owned = [np.unpackbits(tr.masks[t], axis=1, count=width).astype(bool) for tr in others]
        mine = _square_mask(found, config)
        box = landmark_box(found)
        if any(box_iou(box, landmark_box(tr.frames[t])) >= config.revive_iou or same_box(
                box, landmark_box(tr.frames[t]), config) for tr in others) or any(
                same_pixels(mine, theirs, config) for theirs in owned):
            break  # near someone followed: a second reading of them, or a crossing boxes cannot settle
        for theirs in owned:
            mine &= ~theirs
        track.frames[t] = dataclasses.replace(found, segmentation=np.zeros((0, 0), np.float32))
        track.masks[t] = np.packbits(mine, axis=1)
        t -= 1
    return calls


def backfill(tracks: list[_Track], frames: Sequence[np.ndarray], model, config: TrackerConfig) -> int:
    """Follow every run of every track back from where it starts (module docstring), in order of the
    tracks' ids and of the runs. Returns the landmark calls made."""
    if config.backfill < 1:
        return 0
    calls = 0
    for track in sorted(tracks, key=lambda tr: tr.track_id):
        starts = [t for t in sorted(track.frames) if t > 0 and t - 1 not in track.frames]
        for start in starts:
            calls += _fill_before(track, start, tracks, frames, model, config)
    return calls


__all__ = ["backfill", "backward_roi"]
