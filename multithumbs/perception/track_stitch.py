"""One person's track fragments joined once the shot is read.

The forward pass finds a lost person again under their old id when their new box overlaps their last one
(``revive_iou``) or their appearance model says so. A person read poorly behind someone else, lost for a
few frames while walking, comes back too far from their last box for the first, and with no model for
the second: their models learn only from frames where nobody overlaps them. Each such return is a new
track, and every new track is an identity switch in the evaluation (session 16: most of the nothing-
simulated suite's switches are within shots).

Offline, with the whole shot known, a fragment that starts 1 to ``stitch_gap`` frames after another ends
continues it when it starts where the earlier one, moved on at its last velocity, would be (box IoU at
least ``stitch_iou``), when no other person is at least as near that place then, and when the earlier
track's appearance model does not say it is someone else. Pairs are joined closest in time first. A track
that starts the very frame after another ends is a split (:mod:`.track_split`: the appearance models said
the square had moved onto someone else), and is left as it is.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from multithumbs.perception.pose_checks import box_iou
from multithumbs.perception.shot_assembly import landmark_box
from multithumbs.perception.track_appearance import model_dissimilarity

if TYPE_CHECKING:  # annotations only: pose_tracking defines the config and the track
    from multithumbs.perception.pose_tracking import TrackerConfig, _Track


def predicted_box(track: _Track, t: int, steps: int = 3) -> np.ndarray:
    """``track``'s box in frame ``t`` after its last frame: its last box moved on by the mean motion of its
    centre over its last ``steps`` frames (not moved when it has one frame)."""
    frames = sorted(track.frames)[-(steps + 1):]
    last = landmark_box(track.frames[frames[-1]])
    if len(frames) < 2:
        return last
    first = landmark_box(track.frames[frames[0]])
    velocity = (0.5 * (last[:2] + last[2:]) - 0.5 * (first[:2] + first[2:])) / (frames[-1] - frames[0])
    return last + np.tile(velocity * (t - frames[-1]), 2)


def _join(tracks: list[_Track], config: TrackerConfig) -> tuple[_Track, _Track] | None:
    """The pair (earlier, later) to join next, or None."""
    best = None
    for a in tracks:
        a_end = max(a.frames)
        for b in tracks:
            b_start = min(b.frames)
            gap = b_start - a_end - 1
            if b is a or not 1 <= gap <= config.stitch_gap:  # no gap: a split, which appearance decided
                continue
            guess = predicted_box(a, b_start)
            overlap = box_iou(guess, landmark_box(b.frames[b_start]))
            if overlap < config.stitch_iou:
                continue
            if any(box_iou(guess, landmark_box(other.frames[b_start])) >= overlap
                   for other in tracks if other is not a and other is not b and b_start in other.frames):
                continue
            if b.model is not None and model_dissimilarity(a.model, a.model_counts, b.model,
                                                           config.min_model_readings) > config.drift_dissimilarity:
                continue
            key = (gap, -overlap, a.track_id, b.track_id)
            if best is None or key < best[0]:
                best = (key, a, b)
    return None if best is None else (best[1], best[2])


def stitch_fragments(tracks: list[_Track], config: TrackerConfig) -> list[_Track]:
    """``tracks`` with each later fragment of one person merged into the earlier one (module docstring);
    tracks without frames are left out. ``config.stitch_gap`` 0 turns it off."""
    tracks = [tr for tr in tracks if tr.frames]
    if config.stitch_gap < 1:
        return tracks
    while (pair := _join(tracks, config)) is not None:
        a, b = pair
        a.frames.update(b.frames)
        a.masks.update(b.masks)
        a.transit |= b.transit
        tracks.remove(b)
    return tracks


__all__ = ["predicted_box", "stitch_fragments"]
