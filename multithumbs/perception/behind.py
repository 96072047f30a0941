"""A followed person's square read again with everyone else greyed out: someone partly behind another.

BlazePose's landmark model reads one person per square. When the person a track follows walks partly
behind someone, their square holds both, and the model reads the one in front: the reading fits the
track's appearance model badly (dropped as someone else's), or it lands on the person in front's own
track (a duplicate, and the one that slid is lost). The track is then lost for as long as the two
overlap, although half of its person is in view (docs/RESULTS.md, session 31: 90 % of the misses overlap
another person, and in half of them one reading serves both).

Here that square is read once more, on a copy of the frame where every other person read in it is greyed
out (their segmentation, as the detection rounds of :mod:`.pose_tracking` grey out the people they have
found). The new reading is taken only when it is a plausible pose standing within ``behind_max_roll`` of
upright, is no other person's (box, pixels), and fits the track's appearance model like its own person (at
most ``split_dissimilarity``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from multithumbs.perception import blazepose as bp
from multithumbs.perception.pose_checks import box_iou, describe, dissimilarity, plausible, same_box, same_pixels
from multithumbs.perception.shot_assembly import landmark_box

if TYPE_CHECKING:  # annotations only: pose_tracking defines the track
    from multithumbs.perception.pose_tracking import TrackerConfig, _Track


def grey_out(canvas: np.ndarray, found: bp.Landmarks, config: TrackerConfig) -> None:
    """Grey out, in place, a person's pixels (segmentation ≥ ``paint_probability`` within their square)."""
    canvas[pixels(found, config.paint_probability)] = 127


def pixels(found: bp.Landmarks, probability: float) -> np.ndarray:
    """``(H, W)`` bool: a reading's segmentation at ``probability`` or more, within its square."""
    return (found.segmentation >= probability) & found.roi.mask(found.segmentation.shape)


def _square_box(roi: bp.Roi) -> np.ndarray:
    """The axis-aligned box ``(4,)`` around a square."""
    corners = roi.corners()
    return np.concatenate([corners.min(0), corners.max(0)])


def read_behind(frame: np.ndarray, roi: bp.Roi, track: _Track, others: list[tuple[np.ndarray, np.ndarray]], model,
                config: TrackerConfig) -> tuple[tuple[bp.Landmarks, np.ndarray] | None, int]:
    """``track``'s reading in ``roi`` with the others in it greyed out, and its appearance descriptor, or
    None when no one else is in the square or the reading is not taken (module docstring); and the
    landmark calls made (0 or 1).

    Args:
        others: this frame's other people, each as its landmark box ``(4,)`` and its ``(H, W)`` bool
            pixels (those greyed out, and those a reading must not mostly be).
    """
    square = _square_box(roi)
    inside = [(box, mask) for box, mask in others if box_iou(box, square) > 0]
    if not inside:
        return None, 0  # nobody to be behind: the reading failed for another reason
    canvas = frame.copy()
    for _, mask in inside:
        canvas[mask] = 127
    found = model.landmarks(canvas, roi)
    if not plausible(found, config) or abs(bp.roi_from_landmarks(found).rotation) > config.behind_max_roll:
        return None, 1
    mine = pixels(found, config.mask_probability)
    if any(same_box(landmark_box(found), box, config) or same_pixels(mine, mask, config) for box, mask in inside):
        return None, 1
    descriptor = describe(frame, found, config)
    if dissimilarity(track, descriptor, config) > config.split_dissimilarity:
        return None, 1
    return (found, descriptor), 1


__all__ = ["grey_out", "pixels", "read_behind"]
