"""The camera's own motion where each person stands, read from the floor at their feet.

The facing labelling (:mod:`.facing`) reads a walk from the fitted root's motion in the camera frame. When
the camera moves, that motion is the walk minus the camera's. On the suite's dolly shots (0.3 m/s sideways)
a person standing still seems to walk at up to 12 mm a frame, above the labelling's ``min_speed``, so the
fit's small wanderings in depth were read as a walk towards or away from the camera, and readings that
were right were mirrored (a person nearly standing in s11, for all 21 of their frames, ``docs/RESULTS.md``).

The floor next to a person's feet is static and at the feet's depth, so its image motion is the camera's
motion seen at the person's distance. :func:`ground_flow` tracks corners of the floor in a band beside the
feet, outside every person's mask (Shi-Tomasi corners and pyramidal Lucas-Kanade with a forward-backward
check, OpenCV), to the next frame and keeps their median shift. :func:`static_velocity` turns it into the
camera-frame velocity of a static point at the person's root: a point at depth ``Z`` whose image moves by
``(du, dv)`` pixels moves ``(du Z / fx, dv Z / fy)`` metres sideways (first order; the depth component of
the camera's motion is not seen and is left out). The walk is then the root's velocity minus that.

Frames whose feet are not seen, or whose band has too few trackable corners (a plain floor, feet at the
frame's edge), give nothing, and their walk is read as before. A static camera gives a shift near zero.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

FOOT_LANDMARKS: tuple[int, ...] = (27, 28, 29, 30, 31, 32)
"""BlazePose's ankles, heels and foot tips."""


@dataclass(frozen=True)
class GroundMotionConfig:
    """Where and how the floor beside a person's feet is tracked (module docstring)."""

    enabled: bool = True
    """Take the camera's motion, read from the floor at the feet, out of the walk the facing reads."""
    min_visibility: float = 0.5
    """Visibility a foot landmark needs to place the band."""
    band_above: float = 0.06
    """Height of the band above the lowest foot landmark, as a share of the person's landmark box height."""
    band_below: float = 0.1
    """Height of the band below the lowest foot landmark (same unit): the floor in front of the feet."""
    band_side: float = 0.5
    """How far the band reaches left and right of the feet (same unit)."""
    mask_margin: int = 4
    """Pixels every person's mask is grown by before the floor is taken outside it (edges move with them)."""
    max_corners: int = 40
    """Most corners tracked per person and frame."""
    min_corners: int = 6
    """Corners that must be tracked both ways for a frame's shift to count."""
    max_round_trip: float = 0.5
    """Pixels a corner tracked forwards and back may end from where it started."""


def _foot_band(image: np.ndarray, box: np.ndarray, frame_size: tuple[int, int],
               config: GroundMotionConfig) -> tuple[int, int, int, int] | None:
    """``(x0, y0, x1, y1)`` pixel band beside the feet of one reading ``image (33, 5)``, or None."""
    feet = image[list(FOOT_LANDMARKS)]
    seen = feet[:, 3] >= config.min_visibility
    if not seen.any():
        return None
    height = max(float(box[3] - box[1]), 1.0)
    lowest = float(feet[seen, 1].max())
    left, right = float(feet[seen, 0].min()), float(feet[seen, 0].max())
    h, w = frame_size
    x0, x1 = int(max(0, np.floor(left - config.band_side * height))), int(min(w, np.ceil(right + config.band_side * height)))
    y0, y1 = int(max(0, np.floor(lowest - config.band_above * height))), int(min(h, np.ceil(lowest + config.band_below * height)))
    return (x0, y0, x1, y1) if x1 - x0 >= 8 and y1 - y0 >= 8 else None


def ground_flow(frames, image: np.ndarray, boxes: np.ndarray, masks: np.ndarray, valid: np.ndarray,
                config: GroundMotionConfig = GroundMotionConfig()) -> np.ndarray:
    """``(P, T, 2)`` pixels per frame: the median shift from frame ``t`` to ``t + 1`` of the floor beside
    each person's feet; nan where it is not known (the last frame, feet not seen, too few corners).

    Args:
        frames: the shot's ``T`` ``(H, W, 3)`` uint8 RGB frames.
        image: ``(P, T, 33, 5)`` BlazePose's pixel landmarks with visibility (column 3).
        boxes: ``(P, T, 4)`` the landmark boxes.
        masks: ``(P, T, H, ceil(W/8))`` bit-packed person masks.
        valid: ``(P, T)`` bool.
    """
    import cv2

    frames = list(frames)
    num_people, num_frames = np.asarray(valid).shape
    flow = np.full((num_people, num_frames, 2), np.nan)
    if not config.enabled or num_people == 0 or num_frames < 2:
        return flow
    h, w = frames[0].shape[:2]
    kernel = np.ones((2 * config.mask_margin + 1, 2 * config.mask_margin + 1), np.uint8)
    grey = [cv2.cvtColor(np.ascontiguousarray(f), cv2.COLOR_RGB2GRAY) for f in frames]
    lk = dict(winSize=(15, 15), maxLevel=2, criteria=(cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 20, 0.03))
    for t in range(num_frames - 1):
        people = np.flatnonzero(valid[:, t])
        if people.size == 0:
            continue
        bits = np.unpackbits(masks[valid[:, t], t], axis=-1)[..., :w].any(0).astype(np.uint8)
        floor = (cv2.dilate(bits, kernel) == 0).astype(np.uint8) * 255
        for p in people:
            band = _foot_band(image[p, t], boxes[p, t], (h, w), config)
            if band is None:
                continue
            x0, y0, x1, y1 = band
            region = np.zeros((h, w), np.uint8)
            region[y0:y1, x0:x1] = floor[y0:y1, x0:x1]
            corners = cv2.goodFeaturesToTrack(grey[t], config.max_corners, 0.01, 5, mask=region)
            if corners is None or len(corners) < config.min_corners:
                continue
            ahead, ok, _ = cv2.calcOpticalFlowPyrLK(grey[t], grey[t + 1], corners, None, **lk)
            back, ok_back, _ = cv2.calcOpticalFlowPyrLK(grey[t + 1], grey[t], ahead, None, **lk)
            kept = (ok.ravel() == 1) & (ok_back.ravel() == 1) & (
                np.linalg.norm((back - corners).reshape(-1, 2), axis=-1) <= config.max_round_trip)
            if kept.sum() >= config.min_corners:
                flow[p, t] = np.median((ahead - corners).reshape(-1, 2)[kept], axis=0)
    return flow


def static_velocity(flow: np.ndarray, transl: np.ndarray, valid: np.ndarray, K: np.ndarray,
                    window: int) -> np.ndarray:
    """``(P, T, 3)`` metres per frame: the camera-frame velocity of a static point at each person's root,
    from the floor's shift ``flow (P, T, 2)`` averaged over the known frames within ``window`` either side
    and scaled by the root's depth ``transl[..., 2]`` (module docstring); 0 where no shift is known near."""
    flow, transl, valid = np.asarray(flow, np.float64), np.asarray(transl, np.float64), np.asarray(valid, bool)
    known = np.isfinite(flow).all(-1) & valid
    summed = np.where(known[..., None], flow, 0.0)
    num_frames = flow.shape[1]
    # Sums over [t - window, t + window] by a cumulative sum along time.
    csum = np.concatenate([np.zeros_like(summed[:, :1]), np.cumsum(summed, axis=1)], axis=1)
    ccount = np.concatenate([np.zeros_like(known[:, :1], dtype=np.int64), np.cumsum(known, axis=1)], axis=1)
    lo = np.clip(np.arange(num_frames) - window, 0, num_frames)
    hi = np.clip(np.arange(num_frames) + window + 1, 0, num_frames)
    count = ccount[:, hi] - ccount[:, lo]
    mean = (csum[:, hi] - csum[:, lo]) / np.maximum(count, 1)[..., None]
    K = np.asarray(K, np.float64)
    depth = transl[..., 2]
    velocity = np.zeros(transl.shape)
    velocity[..., 0] = mean[..., 0] * depth / K[0, 0]
    velocity[..., 1] = mean[..., 1] * depth / K[1, 1]
    return np.where(((count > 0) & valid)[..., None], velocity, 0.0)


__all__ = ["FOOT_LANDMARKS", "GroundMotionConfig", "ground_flow", "static_velocity"]
