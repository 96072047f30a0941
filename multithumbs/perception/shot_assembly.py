"""The end of each frame and of each shot of :mod:`.pose_tracking`: masks settled between people,
short runs dropped, and the tracks assembled into arrays (:class:`ShotPoses`)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from multithumbs.perception import blazepose as bp

if TYPE_CHECKING:  # annotations only: pose_tracking builds the tracks and the config
    from multithumbs.perception.pose_tracking import TrackerConfig, _Track


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


def landmark_box(landmarks: bp.Landmarks) -> np.ndarray:
    """``(4,)`` x0, y0, x1, y1 around the 33 pose landmarks."""
    points = landmarks.image[: bp.NUM_POSE_LANDMARKS, :2]
    return np.concatenate([points.min(0), points.max(0)])


def drop_short_runs(track: _Track, min_run: int) -> None:
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


def settle_frame(tracks: list[_Track], t: int, config: TrackerConfig) -> None:
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
        probability[k] = found.segmentation * found.roi.mask((h, w))
    owner = probability.argmax(0)
    confident = probability.max(0) >= config.mask_probability
    for k, tr in enumerate(present):
        tr.masks[t] = np.packbits(confident & (owner == k), axis=1)
        tr.frames[t] = dataclasses.replace(tr.frames[t], segmentation=NO_SEGMENTATION)


NO_SEGMENTATION = np.zeros((0, 0), np.float32)
"""What a settled reading keeps of its full-frame segmentation (its mask is in the track's ``masks``)."""


def assemble(tracks: list[_Track], num_frames: int, image_size, config: TrackerConfig, detector_calls: int,
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


__all__ = ["ShotPoses", "NO_SEGMENTATION", "landmark_box", "drop_short_runs", "settle_frame", "assemble"]
