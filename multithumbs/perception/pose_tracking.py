"""Several people through one shot with BlazePose: detect, follow each from its own landmarks, re-detect.

MediaPipe's pose graph follows one person: the square for frame ``t + 1`` comes from frame ``t``'s
auxiliary landmarks, and the detector runs only when that person is lost. Here every tracked person
carries its own square, and the detector runs on the whole frame every ``redetect_every`` frames (and
whenever someone was lost), so people who enter, or who come back after an occlusion, are found:

1. each live track's landmarks are computed in the square its last landmarks give, moved on by their
   last motion; a pose flag below ``min_presence`` marks it missed;
2. on detection frames, everyone followed is greyed out (their segmentation) and the detector runs
   round after round, each time on its best detection: a landmark pass in its square on the real frame
   confirms it, it is greyed out in turn, and it becomes a recently lost track (same box, overlap ≥
   ``revive_iou``) or a new one. The detector was trained for one person per image; greying out the
   people it has given is what lets it give the next (recall 0.64 -> see docs/RESULTS.md);
3. two tracks whose landmark boxes overlap by ``duplicate_iou`` or more, or one nearly inside the other,
   have drifted onto one person: the younger one is marked missed, last seen where it was before. A
   pose whose landmarks shrink into a corner of their square (bodies cut by the frame's edge) is not
   taken;
4. masks: each person's segmentation on the frame, restricted to the square it came from; a pixel
   goes to the person most sure of it, at probability ≥ 0.5.

The detector is anchored on the face (BlazePose): people seen from behind are found late or not at
all, and are carried from their landmarks once found. Ids are local to the shot and never reused.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Iterable

import cv2
import numpy as np

from multithumbs.perception import blazepose as bp


@dataclass(frozen=True)
class TrackerConfig:
    """How people are found and followed within a shot."""

    min_detection_score: float = 0.5
    """Detector score at which a detection starts or revives a track (MediaPipe's pose solution: 0.5)."""
    min_presence: float = 0.5
    """Pose flag below which a person is lost in that frame (MediaPipe's ``min_tracking_confidence``)."""
    redetect_every: int = 1
    """Frames between whole-frame detections while everyone is followed (1: every frame, which finds
    people entering soonest; each detection costs ~12 ms beside ~25 ms per person for the landmarks)."""
    max_people: int = 8
    """Most people followed at once; the detector's weakest new detections wait beyond it."""
    max_missed: int = 15
    """Frames a lost person can be re-found under the same id (short occlusions)."""
    revive_iou: float = 0.3
    """Overlap of a new person's box with a lost one's last box that makes it the same person."""
    duplicate_iou: float = 0.6
    """Overlap of two people's landmark boxes that means they follow one person."""
    nested_fraction: float = 0.8
    """Share of the smaller of two landmark boxes inside the larger that also means one person."""
    mask_overlap: float = 0.7
    """Share of the smaller of two segmentations inside the other that also means one person."""
    min_extent: float = 0.3
    """Smallest long side of a pose's landmark box, as a share of its square's side, for it to count."""
    min_run: int = 3
    """Frames of a track outside a run of this many consecutive ones are dropped."""
    min_frames: int = 6
    """Tracks seen in fewer frames (a quarter second at 24 fps) are dropped: passing misreadings."""
    mask_probability: float = 0.5
    """Segmentation probability at which a pixel belongs to a person."""
    paint_probability: float = 0.3
    """Segmentation probability at which a found person's pixels are greyed out before the next detection."""
    tiles: int = 3
    """Square tiles across the frame's long side the detector also looks at when the whole frame gives
    nothing (below 2: whole frame only)."""
    max_rejections: int = 2
    """Detections a frame may reject (no pose in the landmark pass, someone already followed) before the
    search stops."""


@dataclass(frozen=True)
class ShotPoses:
    """The people BlazePose followed through one shot (``P`` people, ``T`` frames).

    Attributes:
        track_ids: ``(P,)`` local ids in order of appearance.
        image: ``(P, T, 33, 5)`` pixel u, v, z, visibility, presence (0 where not valid).
        world: ``(P, T, 33, 3)`` metres, origin between the hips, camera-aligned axes.
        boxes: ``(P, T, 4)`` x0, y0, x1, y1 of the 33 landmarks.
        masks: ``(P, T, H, ceil(W/8))`` uint8 bit-packed masks.
        valid: ``(P, T)`` bool.
        detector_calls, landmark_calls: model invocations, for the speed split.
    """

    track_ids: np.ndarray
    image: np.ndarray
    world: np.ndarray
    boxes: np.ndarray
    masks: np.ndarray
    valid: np.ndarray
    detector_calls: int = 0
    landmark_calls: int = 0


@dataclass
class _Track:
    track_id: int
    frames: dict = field(default_factory=dict)  # t -> Landmarks (segmentation dropped once the frame is settled)
    masks: dict = field(default_factory=dict)  # t -> (H, ceil(W/8)) packed mask
    last: bp.Landmarks | None = None
    before: bp.Landmarks | None = None  # the landmarks before ``last``
    missed: int = 0

    @property
    def box(self) -> np.ndarray:
        return landmark_box(self.last)


def landmark_box(landmarks: bp.Landmarks) -> np.ndarray:
    """``(4,)`` x0, y0, x1, y1 around the 33 pose landmarks."""
    points = landmarks.image[: bp.NUM_POSE_LANDMARKS, :2]
    return np.concatenate([points.min(0), points.max(0)])


def box_iou(a: np.ndarray, b: np.ndarray) -> float:
    """Intersection over union of two ``(4,)`` boxes."""
    inter = np.prod(np.clip(np.minimum(a[2:], b[2:]) - np.maximum(a[:2], b[:2]), 0, None))
    union = np.prod(a[2:] - a[:2]) + np.prod(b[2:] - b[:2]) - inter
    return float(inter / union) if union > 0 else 0.0


def _plausible(found: bp.Landmarks, config: TrackerConfig) -> bool:
    """A pose whose flag is up and whose landmarks span a body-sized part of their square: a landmark set
    shrunk into a corner of it (seen on bodies cut by the frame's edge) is not a person."""
    box = landmark_box(found)
    return bool(found.presence >= config.min_presence
                and max(box[2] - box[0], box[3] - box[1]) >= config.min_extent * found.roi.size)


def same_person(a: bp.Landmarks, b: bp.Landmarks, config: TrackerConfig) -> bool:
    """Two poses on one person: landmark boxes at IoU ≥ ``duplicate_iou`` or one nearly inside the other,
    or segmentations mostly the same pixels (two readings of one body in different squares, as close-ups
    give)."""
    box_a, box_b = landmark_box(a), landmark_box(b)
    inter = np.prod(np.clip(np.minimum(box_a[2:], box_b[2:]) - np.maximum(box_a[:2], box_b[:2]), 0, None))
    smaller = min(np.prod(box_a[2:] - box_a[:2]), np.prod(box_b[2:] - box_b[:2]))
    if box_iou(box_a, box_b) >= config.duplicate_iou or (smaller > 0 and inter / smaller >= config.nested_fraction):
        return True
    mask_a, mask_b = a.segmentation >= config.mask_probability, b.segmentation >= config.mask_probability
    fewer = min(mask_a.sum(), mask_b.sum())
    return bool(fewer > 0 and (mask_a & mask_b).sum() / fewer >= config.mask_overlap)


def _inside(point: np.ndarray, box: np.ndarray) -> bool:
    return bool(box[0] <= point[0] <= box[2] and box[1] <= point[1] <= box[3])


def _claimed(detection: bp.Detection, live: list[_Track]) -> bool:
    """The detection's face and mid-hip both fall in a live person's box: it is that person."""
    face = detection.face_box.reshape(2, 2).mean(0)
    return any(_inside(face, tr.box) and _inside(detection.keypoints[0], tr.box) for tr in live)


def _predicted_roi(track: _Track, t: int) -> bp.Roi:
    """This frame's square for a track: its last landmarks' square moved on by their last motion (constant
    velocity), so that two people crossing each other keep looking at their own person."""
    roi = bp.roi_from_landmarks(track.last)
    previous = track.frames.get(t - 2)
    if previous is None or t - 1 not in track.frames:
        return roi
    step = 0.5 * (track.last.image[33, :2] - previous.image[33, :2])  # damped: landmark jitter is not motion
    return bp.Roi(roi.centre + step, roi.size, roi.rotation)


def _paint_out(canvas: np.ndarray, found: bp.Landmarks, config: TrackerConfig) -> None:
    """Grey out a person the detector has already given, so that its next pass finds someone else."""
    region = np.zeros(canvas.shape[:2], np.uint8)
    cv2.fillConvexPoly(region, np.round(found.roi.corners()).astype(np.int32), 1)
    canvas[(found.segmentation >= config.paint_probability) & (region > 0)] = 127


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
                 lost: list[_Track], t: int, new_track) -> tuple[int, int]:
    """Detection rounds on a copy of the frame where everyone already followed is greyed out: each round
    takes the detector's best detection, checks it with a landmark pass on the real frame, greys it out
    too, and makes it a revived or a new track. Returns the detector and landmark calls made."""
    canvas = frame.copy()
    for tr in live:
        _paint_out(canvas, tr.last, config)
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
        box = landmark_box(found)
        if not _plausible(found, config) or _claimed(detection, live) or any(same_person(found, tr.last, config)
                                                                             for tr in live):
            x0, y0, x1, y1 = np.round(detection.face_box).astype(int)
            canvas[max(y0, 0):max(y1, 0), max(x0, 0):max(x1, 0)] = 127
            _paint_out(canvas, found, config)
            continue
        overlap = [box_iou(box, tr.box) for tr in lost]
        if overlap and max(overlap) >= config.revive_iou:
            tr = lost.pop(int(np.argmax(overlap)))
        else:
            tr = new_track()
            tracks.append(tr)
        tr.last, tr.frames[t], tr.missed = found, found, 0
        live.append(tr)
        _paint_out(canvas, found, config)
    return calls[0], calls[1]


def track_shot(frames: Iterable[np.ndarray], model, config: TrackerConfig = TrackerConfig(),
               progress=None) -> ShotPoses:
    """Follow the people of one shot (module docstring).

    Args:
        frames: the shot's ``(H, W, 3)`` uint8 RGB frames in order.
        model: a loaded :class:`~multithumbs.perception.blazepose_models.BlazePose` (or anything with its
            ``detect(image)`` and ``landmarks(image, roi)``).
        progress: optional ``callable(done, total_or_None)`` after each frame.
    """
    tracks: list[_Track] = []
    detector_calls = landmark_calls = 0
    image_size = None
    t = -1
    for t, frame in enumerate(frames):
        image_size = frame.shape[:2]
        for tr in tracks:
            if tr.missed:
                tr.missed += 1  # ages every lost track; past max_missed it is never revived
        live = [tr for tr in tracks if tr.missed == 0]
        for tr in live:
            found = model.landmarks(frame, _predicted_roi(tr, t))
            landmark_calls += 1
            if _plausible(found, config):
                tr.before, tr.last, tr.frames[t] = tr.last, found, found
            else:
                tr.missed = 1
        live = [tr for tr in live if tr.missed == 0]
        lost = [tr for tr in tracks if 0 < tr.missed <= config.max_missed]
        if t % config.redetect_every == 0 or lost or not live:
            calls = _find_people(frame, model, config, tracks, live, lost, t, lambda: _Track(len(tracks)))
            detector_calls, landmark_calls = detector_calls + calls[0], landmark_calls + calls[1]
        live.sort(key=lambda tr: tr.track_id)
        for i, a in enumerate(live):
            for b in live[i + 1:]:
                if b.missed == 0 and a.missed == 0 and same_person(a.last, b.last, config):
                    # b followed a onto a's person (its own was hidden): it is lost, last seen where it was.
                    b.frames.pop(t, None)
                    b.last, b.missed = b.before or b.last, 1
        _settle_frame(tracks, t, config)
        if progress:
            progress(t + 1, None)
    for tr in tracks:
        _drop_short_runs(tr, config.min_run)
    return _assemble([tr for tr in tracks if len(tr.frames) >= config.min_frames], t + 1, image_size, config,
                     detector_calls, landmark_calls)


def _drop_short_runs(track: _Track, min_run: int) -> None:
    """Forget a track's frames that are not part of ``min_run`` consecutive ones: an isolated reading has
    nothing to smooth its depth against (fitting judges depth from body size, frame by frame)."""
    frames = sorted(track.frames)
    run: list[int] = []
    for t in frames + [None]:
        if run and (t is None or t != run[-1] + 1):
            if len(run) < min_run:
                for old in run:
                    del track.frames[old]
            run = []
        if t is not None:
            run.append(t)


def _settle_frame(tracks: list[_Track], t: int, config: TrackerConfig) -> None:
    """Frame ``t``'s masks, now that its people are known: each person's segmentation restricted to the
    square it came from, a pixel going to the person most sure of it. The frame's landmarks are then kept
    without their full-frame segmentation (only the last ones keep theirs), so memory grows with the
    shot's length by masks, not by float images."""
    present = [tr for tr in tracks if t in tr.frames]
    if not present:
        return
    h, w = present[0].frames[t].segmentation.shape
    probability = np.zeros((len(present), h, w), np.float32)
    for k, tr in enumerate(present):
        found = tr.frames[t]
        region = np.zeros((h, w), np.uint8)
        cv2.fillConvexPoly(region, np.round(found.roi.corners()).astype(np.int32), 1)
        probability[k] = found.segmentation * region
    owner = probability.argmax(0)
    confident = probability.max(0) >= config.mask_probability
    for k, tr in enumerate(present):
        tr.masks[t] = np.packbits(confident & (owner == k), axis=1)
        tr.frames[t] = dataclasses.replace(tr.frames[t], segmentation=_NO_SEGMENTATION)


_NO_SEGMENTATION = np.zeros((0, 0), np.float32)


def _assemble(tracks: list[_Track], num_frames: int, image_size, config: TrackerConfig, detector_calls: int,
              landmark_calls: int) -> ShotPoses:
    h, w = image_size if image_size is not None else (0, 0)
    p = len(tracks)
    image = np.zeros((p, num_frames, bp.NUM_POSE_LANDMARKS, 5))
    world = np.zeros((p, num_frames, bp.NUM_POSE_LANDMARKS, 3))
    boxes = np.zeros((p, num_frames, 4))
    valid = np.zeros((p, num_frames), bool)
    masks = np.zeros((p, num_frames, h, (w + 7) // 8), np.uint8)
    for i, tr in enumerate(tracks):
        for t, found in tr.frames.items():
            image[i, t] = found.image[: bp.NUM_POSE_LANDMARKS]
            world[i, t] = found.world
            boxes[i, t] = landmark_box(found)
            valid[i, t] = True
            masks[i, t] = tr.masks[t]
    ids = np.array([tr.track_id for tr in tracks], dtype=np.int64)
    return ShotPoses(ids, image, world, boxes, masks, valid, detector_calls, landmark_calls)


__all__ = ["TrackerConfig", "ShotPoses", "track_shot", "landmark_box", "box_iou", "same_person"]
