"""The backward fill at the end of a shot: each track followed back from where it was found, and the
first frames of each run read again from the frames after them.

The detector is anchored on the face, so a person who walks in with their back to the camera, or who is
hidden behind someone, is found frames after they could have been followed: the forward pass of
:mod:`.pose_tracking` has nothing to start from until then. Once the shot is read, every run of a track
(its first frame, and the frame it was found again after a gap) is followed backwards the way the forward
pass follows forwards: frame ``t - 1``'s square comes from frame ``t``'s landmarks, moved on by their last
motion. It stops at the track's previous run, after ``backfill`` frames, or at the first reading that is
not a plausible pose, that fits the track's appearance model poorly (above ``split_dissimilarity``: the
forward pass does not learn from such readings either), or that lands on or near a person already
followed in that frame (box overlap ≥ ``revive_iou``, or :func:`.pose_checks.same_box`, or mostly their
pixels), unless the square, read again with those people greyed out, gives the track's own person
(someone partly behind another, :mod:`.behind`). A filled frame's mask is its segmentation in its square,
less the pixels the frame's other people already own (their masks were settled with the frame).

Before that, :func:`reread_starts` reads the first ``reread`` frames of every run again, backwards, each in
the square of the frame after it. A run's first square comes from a detection (a face-anchored box, or a
person box): the landmarks read in it were often a body seen narrow, in profile, until the square
followed the person a few frames later. Fitted bodies then started 40-130° off the true facing and turned
back over 5-8 frames (the fit's smoothness makes a ramp of them); the first two frames are what W-MPJPE
aligns on (``docs/RESULTS.md``, session 22). A reading that is not a plausible pose, or lands on someone
else, ends the re-reading of that run and keeps what was read forwards; masks stay as settled.
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING, Sequence

import numpy as np

from multithumbs.perception import blazepose as bp
from multithumbs.perception.behind import pixels, read_behind
from multithumbs.perception.pose_checks import (box_iou, describe, dissimilarity, moved_square, plausible, same_box,
                                                same_pixels)
from multithumbs.perception.shot_assembly import NO_SEGMENTATION, landmark_box

if TYPE_CHECKING:  # annotations only: pose_tracking defines the config and the track
    from multithumbs.perception.pose_tracking import TrackerConfig, _Track


def backward_roi(track: _Track, t: int) -> bp.Roi:
    """Frame ``t``'s square for a track read in frame ``t + 1``: that reading's square, moved on by the
    motion from ``t + 2`` to ``t + 1`` (:func:`.pose_checks.moved_square`, as forwards)."""
    return moved_square(track.frames[t + 1], track.frames.get(t + 2))


def _near_someone(box: np.ndarray, others: list[_Track], t: int, config: TrackerConfig) -> bool:
    """A landmark box overlapping one of ``others``' in frame ``t`` by ``revive_iou`` or more, or on the
    same person by :func:`.pose_checks.same_box` (nearly inside)."""
    return any(box_iou(box, theirs) >= config.revive_iou or same_box(box, theirs, config)
               for theirs in (landmark_box(tr.frames[t]) for tr in others))


def _fill_before(track: _Track, start: int, tracks: list[_Track], frames: Sequence[np.ndarray], model,
                 config: TrackerConfig) -> int:
    """Follow ``track`` back from frame ``start`` (module docstring). Returns the landmark calls made."""
    calls = 0
    t = start - 1
    while t >= 0 and t not in track.frames and start - t <= config.backfill:
        square = backward_roi(track, t)
        found = model.landmarks(frames[t], square)
        calls += 1
        others = [tr for tr in tracks if tr is not track and t in tr.frames]
        owned = [np.unpackbits(tr.masks[t], axis=1, count=frames[t].shape[1]).astype(bool) for tr in others]
        if not _own_reading(found, track, frames[t], others, owned, t, config):
            if not config.read_behind:
                break
            # perhaps behind one of them: read again with them greyed out (.behind)
            got, used = read_behind(frames[t], square, track, [(landmark_box(tr.frames[t]), mask)
                                                               for tr, mask in zip(others, owned)], model, config)
            calls += used
            if got is None:
                break
            found = got[0]
        mine = pixels(found, config.mask_probability)
        for theirs in owned:
            mine &= ~theirs
        track.frames[t] = dataclasses.replace(found, segmentation=NO_SEGMENTATION)
        track.masks[t] = np.packbits(mine, axis=1)
        t -= 1
    return calls


def _own_reading(found: bp.Landmarks, track: _Track, frame: np.ndarray, others: list[_Track], owned: list[np.ndarray],
                 t: int, config: TrackerConfig) -> bool:
    """A backward reading is the track's own person: a plausible pose, not on or near someone followed in
    frame ``t`` (a second reading of them, or a crossing boxes cannot settle), like the track's model
    (forwards, readings above ``split_dissimilarity`` are not learnt from), and not mostly the pixels
    another person owns."""
    if not plausible(found, config) or _near_someone(landmark_box(found), others, t, config):
        return False
    if dissimilarity(track, describe(frame, found, config), config) > config.split_dissimilarity:
        return False
    mine = pixels(found, config.mask_probability)
    return not any(same_pixels(mine, theirs, config) for theirs in owned)


def reread_starts(tracks: list[_Track], frames: Sequence[np.ndarray], model, config: TrackerConfig) -> int:
    """Read the first ``config.reread`` frames of every run of every track again, backwards from the frame
    after them (module docstring). Returns the landmark calls made."""
    calls = 0
    for track in sorted(tracks, key=lambda tr: tr.track_id):
        for start in [t for t in sorted(track.frames) if t - 1 not in track.frames]:
            for t in range(start + config.reread - 1, start - 1, -1):
                if t + 1 not in track.frames or t not in track.frames:
                    continue  # a run shorter than the re-read: its last frame keeps its reading
                found = model.landmarks(frames[t], backward_roi(track, t))
                calls += 1
                others = [tr for tr in tracks if tr is not track and t in tr.frames]
                if not plausible(found, config) or _near_someone(landmark_box(found), others, t, config):
                    break
                track.frames[t] = dataclasses.replace(found, segmentation=NO_SEGMENTATION)
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


__all__ = ["backfill", "backward_roi", "reread_starts"]
