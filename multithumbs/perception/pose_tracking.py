"""Several people through one shot with BlazePose: detect, follow each from its own landmarks, re-detect.

MediaPipe's pose graph follows one person: the square for frame ``t + 1`` comes from frame ``t``'s
auxiliary landmarks, and the detector runs only when that person is lost. Here every tracked person
carries its own square, and the detector runs on the whole frame every ``redetect_every`` frames (and
whenever someone was lost), so people who enter, or who come back after an occlusion, are found:

1. each live track's landmarks are computed in the square its last landmarks give, moved on by their
   last motion; a pose flag below ``min_presence``, or a reading unlike the track's appearance model
   (below), marks it missed, unless the square, read again with the others read in it greyed out, gives
   the track's own person (someone partly behind another, :mod:`.behind`);
2. on detection frames, everyone followed is greyed out (their segmentation) and the detector runs
   round after round, each time on its best detection: a landmark pass in its square on the real frame
   confirms it, it is greyed out in turn, and it becomes a recently lost track (same box, overlap ≥
   ``revive_iou``) or a new one. The detector was trained for one person per image; greying out the
   people it has given is what lets it give the next (recall 0.64 -> see docs/RESULTS.md). Then the
   boxes a whole-body person detector sees where no one is followed each get a landmark pass too
   (:mod:`.person_proposals`; NanoDet, :mod:`.nanodet`, by default, else OpenCV's HOG): it finds people
   by their body, whom the face-anchored one misses. A box whose centre lies in a followed person's box,
   but which is not theirs, is someone partly behind them: it is read with everyone followed greyed out;
3. two tracks whose landmark boxes overlap by ``duplicate_iou`` or more, or one nearly inside the other,
   have drifted onto one person: the younger one is marked missed, last seen where it was before (unless
   its square, read again with the others greyed out, gives its own person, as in step 1). A
   pose whose landmarks shrink into a corner of their square (bodies cut by the frame's edge) is not
   taken;
4. masks: each person's segmentation on the frame, restricted to the square it came from; a pixel
   goes to the person most sure of it, at probability ≥ 0.5 (:mod:`.shot_assembly`);
5. once the shot is read, the first frames of each run of each track are read again backwards, in the
   squares the following frames give, and each run is followed back from where it was found
   (:mod:`.backfill`): people the face-anchored detector found late are carried back to where the
   landmark model first sees them; then a track that starts a few frames after another ends, where
   that one was heading, continues it (:mod:`.track_stitch`).

Each track also keeps a model of its appearance (:mod:`.track_appearance`), learnt in frames where it
overlaps nobody: a reading unlike it is someone else's and is dropped (step 1), the track whose model fits
worse is the one that slid in a duplicate (step 3), and a person found again takes the lost track whose
model fits clearly better than the best-overlapping one's, or, after a gap too long for boxes to mean
anything (``relink_missed``), the one whose model alone fits (step 2). Readings that fit the model poorly
but not badly enough to be dropped are not learnt from, and ``split_frames`` of them in a row split the
track: a hidden person's square has slid onto someone no track followed, who gets a track of their own
from the first of them, while the hidden person's track is lost with its model intact (step 1;
:mod:`.track_split`, which also merges a split back when its readings come to fit the old model again).
Once the shot is read, a split that stands loses those first readings: the square was in transit between
the two people, and they are partly each.

The detector is anchored on the face (BlazePose): people seen from behind are found late or not at
all, and are carried from their landmarks once found. Ids are local to the shot and never reused.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Iterable, Sequence

import numpy as np

from multithumbs.perception import blazepose as bp
from multithumbs.perception.backfill import backfill, reread_starts
from multithumbs.perception.behind import grey_out, pixels, read_behind
from multithumbs.perception.person_proposals import hog_boxes, proposal_roi
from multithumbs.perception.pose_checks import box_iou, describe, dissimilarity, moved_square, plausible, same_person
from multithumbs.perception.shot_assembly import ShotPoses, assemble, drop_short_runs, landmark_box, settle_frame
from multithumbs.perception.track_appearance import clearly_better, updated_model
from multithumbs.perception.track_split import drop_transit, merged_back, moved, remember_fit, split
from multithumbs.perception.track_stitch import stitch_fragments
from multithumbs.perception.tracker_config import TrackerConfig


@dataclass
class _Track:
    track_id: int
    frames: dict = field(default_factory=dict)  # t -> Landmarks (segmentation dropped once the frame is settled)
    masks: dict = field(default_factory=dict)  # t -> (H, ceil(W/8)) packed mask
    last: bp.Landmarks | None = None
    before: bp.Landmarks | None = None  # the landmarks before ``last``
    missed: int = 0
    model: np.ndarray | None = None  # appearance model (track_appearance) and its readings per region
    model_counts: np.ndarray | None = None
    descriptors: dict = field(default_factory=dict)  # t -> this frame's reading's descriptor (until settled)
    unlike: list = field(default_factory=list)  # the latest consecutive frames whose readings fit the model poorly
    fits: list = field(default_factory=list)  # the model's dissimilarity to the last 5 readings that fitted it as usual (track_split)
    split_from: "_Track | None" = None  # the track this one was split from, while it may still be merged back
    alike: int = 0  # this track's latest readings in a row that fit ``split_from``'s model well
    transit: set = field(default_factory=set)  # frames a split read in transit, dropped at the end (track_split)

    @property
    def box(self) -> np.ndarray:
        return landmark_box(self.last)


def _inside(point: np.ndarray, box: np.ndarray) -> bool:
    return bool(box[0] <= point[0] <= box[2] and box[1] <= point[1] <= box[3])


def _claimed(detection: bp.Detection, live: list[_Track]) -> bool:
    """The detection's face and mid-hip both fall in a live person's box: it is that person."""
    face = detection.face_box.reshape(2, 2).mean(0)
    return any(_inside(face, tr.box) and _inside(detection.keypoints[0], tr.box) for tr in live)


def _predicted_roi(track: _Track, t: int) -> bp.Roi:
    """This frame's square for a track: its last landmarks' square moved on by their last motion (constant
    velocity), so that two people crossing each other keep looking at their own person."""
    return moved_square(track.last, track.frames.get(t - 2) if t - 1 in track.frames else None)


def _best_detection(canvas: np.ndarray, model, config: TrackerConfig) -> tuple[bp.Detection | None, int]:
    """The detector's best detection on the whole frame, else on square tiles across its long side (a
    tile is seen at up to ``long side / short side`` times the resolution: smaller people are found).
    Returns it (or None) and the detector calls made."""
    found = model.detect(canvas, min_score=config.min_detection_score)
    if found or config.tiles < 2:
        return (found[0] if found else None), 1
    h, w = canvas.shape[:2]
    side = min(h, w)
    best, calls = None, 1
    for start in np.linspace(0, max(h, w) - side, config.tiles).round().astype(int):
        x0, y0 = (start, 0) if w >= h else (0, start)
        found = model.detect(canvas[y0:y0 + side, x0:x0 + side], min_score=config.min_detection_score)
        calls += 1
        if found and (best is None or found[0].score > best.score):
            shift = np.array([x0, y0])
            best = bp.Detection(found[0].score, found[0].face_box + np.tile(shift, 2), found[0].keypoints + shift)
    return best, calls


def _find_people(frame: np.ndarray, model, config: TrackerConfig, tracks: list[_Track], live: list[_Track],
                 lost: list[_Track], t: int, new_track, people=None) -> tuple[int, int]:
    """Detection rounds on a copy of the frame where everyone already followed is greyed out: each round
    takes the detector's best detection, checks it with a landmark pass on the real frame, greys it out
    too, and makes it a revived or a new track. Then the person detector's proposals (``people``, else HOG's)
    no one followed get a landmark pass each (:mod:`.person_proposals`). Returns the detector and landmark
    calls made."""
    canvas = frame.copy()
    for tr in live:
        grey_out(canvas, tr.last, config)
    calls = [0, 0]
    for _ in range(config.max_people - len(live) + config.max_rejections):
        if len(live) >= config.max_people:
            break
        detection, used = _best_detection(canvas, model, config)
        calls[0] += used
        if detection is None:
            break
        found = model.landmarks(frame, bp.roi_from_detection(detection))
        calls[1] += 1
        if _claimed(detection, live) or not _take(found, frame, config, tracks, live, lost, t, new_track):
            x0, y0, x1, y1 = np.round(detection.face_box).astype(int)
            canvas[max(y0, 0):max(y1, 0), max(x0, 0):max(x1, 0)] = 127
        grey_out(canvas, found, config)
    if config.proposals and len(live) < config.max_people:
        boxes = (people(frame) if people is not None
                 else hog_boxes(frame, config.proposal_scales, config.proposal_min_weight))
        for box in boxes:
            if len(live) >= config.max_people:
                break
            covering = [tr for tr in live if _inside(0.5 * (box[:2] + box[2:4]), tr.box)]
            if covering and (not config.proposal_behind
                             or any(box_iou(box[:4], tr.box) >= config.proposal_same_iou for tr in covering)):
                continue
            # Someone partly behind a followed person: read on the canvas where the followed are greyed out,
            # as the detection rounds do, so the landmark model does not read the person in front again.
            image = canvas if covering else frame
            roi, used = proposal_roi(image, box, model, config.proposal_side, config.proposal_zoom,
                                     config.min_detection_score)
            calls[0] += used
            calls[1] += 1
            found = model.landmarks(image, roi)
            if _take(found, frame, config, tracks, live, lost, t, new_track):
                grey_out(canvas, found, config)
    return calls[0], calls[1]


def _take(found: bp.Landmarks, frame: np.ndarray, config: TrackerConfig, tracks: list[_Track], live: list[_Track],
          lost: list[_Track], t: int, new_track) -> bool:
    """Make a landmark pass a revived or a new live track, unless it is too small, not a plausible pose,
    or someone already followed. Returns whether it was taken."""
    box = landmark_box(found)
    if (box[3] - box[1] < config.min_height * frame.shape[0] or not plausible(found, config)
            or any(same_person(found, tr.last, config) for tr in live)):
        return False
    descriptor = describe(frame, found, config)
    tr = _lost_track_for(box, descriptor, lost, config)
    if tr is not None:
        lost.remove(tr)
    else:
        tr = new_track()
        tracks.append(tr)
    tr.last, tr.frames[t], tr.missed = found, found, 0
    tr.descriptors[t] = descriptor
    live.append(tr)
    return True


def track_shot(frames: Iterable[np.ndarray], model, config: TrackerConfig = TrackerConfig(),
               progress=None, people=None) -> ShotPoses:
    """Follow the people of one shot (module docstring).

    Args:
        frames: the shot's ``(H, W, 3)`` uint8 RGB frames in order.
        model: a loaded :class:`~multithumbs.perception.blazepose_models.BlazePose` (or anything with its
            ``detect(image)`` and ``landmarks(image, roi)``).
        progress: optional ``callable(done, total_or_None)`` after each frame.
        people: optional ``callable(frame) -> (N, 5)`` person boxes and scores, best first, used as the
            proposals instead of HOG's (a loaded :class:`~multithumbs.perception.nanodet.NanoDet`'s ``people``).
    """
    if (config.backfill or config.reread) and not isinstance(frames, Sequence | np.ndarray):
        frames = list(frames)  # the backward fill and the re-read read them again
    tracks: list[_Track] = []
    detector_calls = landmark_calls = 0
    image_size = None
    t = -1
    for t, frame in enumerate(frames):
        image_size = frame.shape[:2]
        for tr in tracks:
            if tr.missed:
                tr.missed += 1  # ages every lost track; past max_missed only its appearance can revive it
        live = [tr for tr in tracks if tr.missed == 0]
        horizon = max(config.max_missed, config.relink_missed) if config.appearance else config.max_missed
        squares, dropped = {}, []
        for tr in live:
            squares[tr.track_id] = _predicted_roi(tr, t)
            found = model.landmarks(frame, squares[tr.track_id])
            landmark_calls += 1
            descriptor = describe(frame, found, config) if plausible(found, config) else None
            fit = dissimilarity(tr, descriptor, config) if descriptor is not None else float("nan")
            # A reading unlike the track's own person has slid onto someone else: lost, last seen where it was.
            if descriptor is None or fit > config.drift_dissimilarity:
                tr.missed, tr.unlike = 1, []
                dropped.append(tr)
                continue
            tr.before, tr.last, tr.frames[t] = tr.last, found, found
            tr.descriptors[t] = descriptor
            if config.merge_splits and tr.split_from is not None and merged_back(tr, descriptor, config, horizon):
                continue
            if fit > config.split_dissimilarity:
                tr.unlike.append(t)
            else:
                tr.unlike = []
                remember_fit(tr, fit, config)
        if config.read_behind:
            for tr in dropped:  # perhaps behind someone: read again with the others greyed out (.behind)
                landmark_calls += _reread_behind(tr, frame, squares[tr.track_id], tracks, t, model, config)[0]
        live = [split(tr, t, tracks, lambda: _Track(len(tracks))) if moved(tr, config) else tr
                for tr in list(tracks) if tr.missed == 0]
        lost = [tr for tr in tracks if 0 < tr.missed <= horizon]
        if t % config.redetect_every == 0 or lost or not live:
            looks = people if people is None or t % config.proposal_every == 0 else (lambda _: np.zeros((0, 5)))
            calls = _find_people(frame, model, config, tracks, live, lost, t, lambda: _Track(len(tracks)), looks)
            detector_calls, landmark_calls = detector_calls + calls[0], landmark_calls + calls[1]
        live.sort(key=lambda tr: tr.track_id)
        for i, a in enumerate(live):
            for b in live[i + 1:]:
                if b.missed == 0 and a.missed == 0 and same_person(a.last, b.last, config):
                    # One followed the other onto its person (its own was hidden): it is lost, last seen
                    # where it was. The one whose model fits worse, else the younger.
                    slid = _slid_onto_other(a, b, t, config)
                    if config.read_behind and slid.track_id in squares:
                        calls, taken = _reread_behind(slid, frame, squares[slid.track_id], tracks, t, model, config,
                                                      replace=True)
                        landmark_calls += calls
                        if taken:
                            continue
                    slid.frames.pop(t, None)
                    slid.descriptors.pop(t, None)
                    slid.last, slid.missed, slid.unlike = slid.before or slid.last, 1, []
        _learn_appearance(tracks, t, config)
        settle_frame(tracks, t, config)
        if progress:
            progress(t + 1, None)
    landmark_calls += reread_starts(tracks, frames, model, config) + backfill(tracks, frames, model, config)
    tracks = stitch_fragments(tracks, config)
    for tr in tracks:
        drop_transit(tr, config)
        drop_short_runs(tr, config.min_run)
    return assemble([tr for tr in tracks if len(tr.frames) >= config.min_frames], t + 1, image_size, config,
                     detector_calls, landmark_calls)


def _reread_behind(track: _Track, frame: np.ndarray, square: bp.Roi, tracks: list[_Track], t: int, model,
                   config: TrackerConfig, replace: bool = False) -> tuple[int, bool]:
    """Read ``track``'s square in frame ``t`` again with the others read in it greyed out
    (:func:`.behind.read_behind`); a reading taken makes the track live in frame ``t`` (``replace``: its
    reading there, a duplicate of another's, is replaced). Returns the landmark calls made (0 or 1) and
    whether a reading was taken."""
    others = [(landmark_box(tr.frames[t]), pixels(tr.frames[t], config.paint_probability))
              for tr in tracks if tr is not track and t in tr.frames]
    got, calls = read_behind(frame, square, track, others, model, config)
    if got is None:
        return calls, False
    found, descriptor = got
    if not replace:
        track.before = track.last
    track.last, track.frames[t], track.missed, track.unlike = found, found, 0, []
    track.descriptors[t] = descriptor
    return calls, True


def _lost_track_for(box: np.ndarray, descriptor: np.ndarray, lost: list[_Track],
                    config: TrackerConfig) -> _Track | None:
    """The lost track a person found again at ``box`` continues, or None (a new person).

    Recently lost tracks whose last box overlaps by ``revive_iou`` or more are the candidates, the best
    overlap first, unless another candidate's model fits clearly better (and at most ``split_dissimilarity``). A candidate whose model says the
    person is someone else is not taken; then, or with no candidate, the lost track whose model alone
    fits clearly best and closely enough (``relink_dissimilarity``) is taken.
    """
    fit = {id(tr): dissimilarity(tr, descriptor, config) for tr in lost}  # each model asked once
    recent = [tr for tr in lost if tr.missed <= config.max_missed]
    overlap = [box_iou(box, tr.box) for tr in recent]
    near = [tr for tr, o in zip(recent, overlap) if o >= config.revive_iou]
    if near:
        # A model that finds the person unlike its own (above split_dissimilarity) is no evidence for its
        # track: it must not win over a better-overlapping track that has no model yet (s02, session 18).
        better = clearly_better([fit[id(tr)] if fit[id(tr)] <= config.split_dissimilarity else float("nan")
                                 for tr in near], config.appearance_margin)
        pick = near[better] if better is not None else recent[int(np.argmax(overlap))]
        if not fit[id(pick)] > config.drift_dissimilarity:
            return pick
    if not config.appearance:
        return None
    best = clearly_better([fit[id(tr)] for tr in lost], config.appearance_margin)
    return lost[best] if best is not None and fit[id(lost[best])] <= config.relink_dissimilarity else None


def _slid_onto_other(a: _Track, b: _Track, t: int, config: TrackerConfig) -> _Track:
    """Of two tracks reading one person in frame ``t``, the one that slid there: the one whose model fits
    its reading clearly worse, else the younger ``b``."""
    fits = [dissimilarity(tr, tr.descriptors.get(t), config) for tr in (a, b)]
    return a if clearly_better(fits, config.appearance_margin) == 1 else b


def _learn_appearance(tracks: list[_Track], t: int, config: TrackerConfig) -> None:
    """Each track read in frame ``t`` whose box overlaps nobody else's learns its reading's appearance."""
    present = [tr for tr in tracks if t in tr.frames and tr.descriptors.get(t) is not None]
    boxes = [landmark_box(tr.frames[t]) for tr in present]
    for i, tr in enumerate(present):
        if config.appearance and not tr.unlike and all(box_iou(boxes[i], other) <= config.isolation_iou
                                     for j, other in enumerate(boxes) if j != i):
            tr.model, tr.model_counts = updated_model(tr.model, tr.model_counts, tr.descriptors[t],
                                                      config.model_memory)
    for tr in tracks:
        tr.descriptors.clear()


__all__ = ["TrackerConfig", "ShotPoses", "track_shot", "landmark_box", "box_iou", "same_person"]
