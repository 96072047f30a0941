"""Splitting a track whose readings stopped fitting its appearance model, and merging the split back.

A hidden person's square can slide onto the person in front, whom no track follows: the readings then
fit the track's model (:mod:`.track_appearance`) poorly but not badly enough to be dropped, and the model
would learn the wrong person. ``split_frames`` such readings in a row, after a model that fitted well
(its last 5 good fits' median at least ``split_jump`` below ``split_dissimilarity``), become a new track
from the first of them, and the old track is lost, its model kept, for when its person is found again.

The same streak also comes from the track's own person read poorly: half hidden behind someone whose
pixels its segmentation takes in, or a model learnt from partial readings. So a track split off keeps a
link to the one it came from while that one is lost: when ``split_frames`` of its readings in a row fit
the old model as well as its readings did before (at most ``split_dissimilarity - split_jump``), it was
the same person, and its frames go back under the old id (on the standard suite's s04, the crossing that
split the front man's track; ``docs/RESULTS.md``, session 14).

A square sliding onto someone else reads a little more of them each frame: its first readings fit only a
little worse before they fit badly. Taken into the typical fit, they would raise it past where the streak
after them splits the track (the standard suite's s02: fits 0.29 and 0.26 took the median from 0.14 to 0.21,
and a track that moved onto someone else stayed whole). So a fit more than ``split_jump`` above the typical
one is not taken into it (:func:`remember_fit`).

The streak a split takes is the square in transit: its readings are partly the old person and partly the
new one (the standard suite's s11, shot 2: a square that slid from the person in pink trousers onto the
person in the green top read the first's legs under the second's head for the 3 frames of the streak,
21-32 px from the second's joints against 8-10 after). Once the shot is read, a split that stands keeps its
track but not those frames (``drop_transit``, :func:`drop_transit`): a body fitted to them is neither
person, and the evaluation's box around it matched the first person, under the second's id.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from multithumbs.perception.pose_checks import dissimilarity

if TYPE_CHECKING:  # annotations only: pose_tracking defines the config and the track
    from multithumbs.perception.pose_tracking import TrackerConfig, _Track


def moved(track: _Track, config: TrackerConfig) -> bool:
    """The track's latest readings are ``split_frames`` in a row unlike a model that used to fit it well."""
    return bool(len(track.unlike) >= config.split_frames and track.fits
                and np.median(track.fits) <= config.split_dissimilarity - config.split_jump)


def remember_fit(track: _Track, fit: float, config: TrackerConfig) -> None:
    """Take a reading's ``fit`` into the track's typical fits (its last 5), unless it is NaN (no model yet)
    or more than ``split_jump`` above their median (module docstring)."""
    if fit != fit or (track.fits and fit > np.median(track.fits) + config.split_jump):
        return
    track.fits = (track.fits + [fit])[-5:]


def split(track: _Track, t: int, tracks: list[_Track], new_track) -> _Track:
    """A track whose latest readings (``track.unlike``) are all unlike its model has moved onto someone
    else: those readings become a new track, which carries on, and the old one is lost, last seen at its
    reading before them, with its model kept for when its person is found again. Returns the new track."""
    child = new_track()
    tracks.append(child)
    for s in track.unlike:
        child.frames[s] = track.frames.pop(s)
        for kept, taken in ((track.masks, child.masks), (track.descriptors, child.descriptors)):
            if s in kept:
                taken[s] = kept.pop(s)
    child.last, child.before, child.split_from = track.last, track.before, track
    child.transit = set(track.unlike)
    track.last, track.before = track.frames[max(track.frames)], None
    track.missed, track.unlike = t - min(child.frames) + 1, []
    return child


def merged_back(track: _Track, descriptor: np.ndarray, config: TrackerConfig, horizon: int) -> bool:
    """Whether ``track``, split from ``track.split_from`` and read in this frame as ``descriptor``, has now
    been merged back into it (module docstring): its frames, masks and descriptors moved under the old id,
    which is live again, and itself emptied for good. ``horizon``: the frames a lost track can be found
    again in; past it, or once the old track is found on its own, the split stands."""
    parent = track.split_from
    if parent.missed == 0 or parent.missed > horizon:
        track.split_from = None  # found again on its own, or gone: the split stands
        return False
    fit = dissimilarity(parent, descriptor, config)
    track.alike = track.alike + 1 if fit <= config.split_dissimilarity - config.split_jump else 0
    if track.alike < config.split_frames:
        return False
    for kept, taken in ((track.frames, parent.frames), (track.masks, parent.masks),
                        (track.descriptors, parent.descriptors)):
        taken.update(kept)
        kept.clear()
    parent.last, parent.before, parent.missed, parent.unlike = track.last, track.before, 0, []
    track.missed, track.split_from = horizon + 1, None  # emptied, never revived
    return True


def drop_transit(track: _Track, config: TrackerConfig) -> None:
    """Forget the frames a split that stands read in transit (module docstring), when ``config.drop_transit``."""
    if not config.drop_transit:
        return
    for t in track.transit:
        track.frames.pop(t, None)
        track.masks.pop(t, None)
    track.transit = set()


__all__ = ["moved", "remember_fit", "split", "merged_back", "drop_transit"]
