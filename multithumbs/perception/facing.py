"""Front/back confusions of a single-image pose estimator, resolved by the way a person walks.

From one image, a body seen from behind and the same body seen from the front, mirrored through the
image plane, give the same picture up to shading. BlazePose, trained on people whose faces show, often
takes a back for a front: it then names the right shoulder "left" (and every other side) and puts
the limbs' depths on the wrong side of the hips. Its visibility does not flag it. On the suite's
faceless people these frames are most of the 2D error (``docs/RESULTS.md``, issue 16).

The walk tells the two readings apart: people walk forwards. Where a person's fitted body faces away
from the direction the fit's own root moves (camera frame, a least-squares line over a few frames), the
frame's reading is replaced by its mirror: sides swapped, depths relative to the hips negated. The
depth trajectory is the fit's, so this works where the person walks towards or away from the camera,
which is where the confusion happens; a person who stands, or walks across the view, is left alone,
and so is a frame whose legs are not all seen: on close-ups (Megamind.avi) the fitted depth wanders,
and judging those frames too mirrored 132 of 472 person-frames of real, front-facing people (leaving
them alone: 1).
A person walking backwards would be mirrored wrongly; so would one whose camera-frame motion is the
camera's own (a dolly faster than the walk). Both are rare in the footage the method is for.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

BLAZEPOSE_MIRROR: tuple[int, ...] = (0, 4, 5, 6, 1, 2, 3, 8, 7, 10, 9, 12, 11, 14, 13, 16, 15, 18, 17, 20, 19, 22,
                                     21, 24, 23, 26, 25, 28, 27, 30, 29, 32, 31)
"""BlazePose's 33 landmarks with left and right exchanged (nose 0; eyes 1-3 / 4-6; ears 7 / 8; mouth
9 / 10; then shoulders, elbows, wrists, pinkies, index fingers, thumbs, hips, knees, ankles, heels and
foot tips in left / right pairs from 11 / 12 to 31 / 32)."""


@dataclass(frozen=True)
class FacingConfig:
    """When a frame's reading is taken for a back seen as a front (module docstring)."""

    enabled: bool = True
    """Mirror the readings of people who face away from where they walk."""
    min_speed: float = 0.005
    """Metres per frame (0.12 m/s at 24 fps) the fitted root must move for the walk to say anything."""
    max_agreement: float = -0.3
    """Cosine between the fitted body's forward and its motion below which the frame is mirrored."""
    window: int = 8
    """Frames either side of a frame whose fitted roots give its motion."""
    min_leg_visibility: float = 0.5
    """Visibility every hip, knee and ankle landmark needs for the frame to be judged: a walk is read from
    a whole body; close-ups (faces and shoulders, whose fitted depth wanders) are left alone."""


def mirrored(image: np.ndarray, world: np.ndarray, flip: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """BlazePose's landmarks with the frames ``flip`` marks replaced by their mirror reading.

    Args:
        image: ``(..., 33, C>=3)`` pixel u, v, relative depth z, then any per-landmark scores.
        world: ``(..., 33, 3)`` metres, origin between the hips, camera-aligned axes.
        flip: ``(...)`` bool.
    Returns:
        ``(image, world)`` copies: in flipped frames the sides are exchanged (positions and scores go with
        the anatomical name), and depth z is negated relative to the hips (world) or to the landmarks'
        own hip mid-point (image).
    """
    image, world = np.array(image, dtype=np.float64), np.array(world, dtype=np.float64)
    order = np.asarray(BLAZEPOSE_MIRROR)
    flip = np.asarray(flip, bool)
    swapped_image, swapped_world = image[..., order, :], world[..., order, :]
    hips_z = 0.5 * (swapped_image[..., 23:24, 2] + swapped_image[..., 24:25, 2])
    swapped_image[..., 2] = 2 * hips_z - swapped_image[..., 2]
    swapped_world[..., 2] = -swapped_world[..., 2]
    return (np.where(flip[..., None, None], swapped_image, image),
            np.where(flip[..., None, None], swapped_world, world))


def body_forward(joints: np.ndarray) -> np.ndarray:
    """Unit forward direction ``(..., 3)`` of SMPL-order joints ``(..., 24, 3)``: across the hips (left
    minus right) crossed with up the spine (neck minus pelvis), which is SMPL's +z at rest."""
    joints = np.asarray(joints, dtype=np.float64)
    forward = np.cross(joints[..., 1, :] - joints[..., 2, :], joints[..., 12, :] - joints[..., 0, :])
    return forward / np.maximum(np.linalg.norm(forward, axis=-1, keepdims=True), 1e-12)


def root_velocity(transl: np.ndarray, valid: np.ndarray, window: int) -> np.ndarray:
    """Per-frame velocity ``(P, T, 3)`` (units per frame): the slope of a least-squares line through the
    valid roots ``transl (P, T, 3)`` within ``window`` frames either side; nan in invalid frames and where
    fewer than 3 valid frames are near."""
    transl, valid = np.asarray(transl, dtype=np.float64), np.asarray(valid, bool)
    velocity = np.full(transl.shape, np.nan)
    num_frames = valid.shape[1]
    for p, t in zip(*np.nonzero(valid)):
        a, b = max(0, t - window), min(num_frames, t + window + 1)
        times = np.arange(a, b)[valid[p, a:b]]
        if times.size < 3:
            continue
        centred = times - times.mean()
        velocity[p, t] = centred @ (transl[p, times] - transl[p, times].mean(0)) / (centred @ centred)
    return velocity


def facing_flips(forward: np.ndarray, velocity: np.ndarray, valid: np.ndarray,
                 config: FacingConfig = FacingConfig()) -> np.ndarray:
    """``(P, T)`` bool: the frames whose reading faces away from the walk (module docstring).

    Args:
        forward: ``(P, T, 3)`` unit forward of the fitted bodies (:func:`body_forward`).
        velocity: ``(P, T, 3)`` their roots' motion per frame (:func:`root_velocity`); nan where unknown.
        valid: ``(P, T)`` bool, the frames that may be judged.
    """
    velocity = np.asarray(velocity, dtype=np.float64)
    known = np.isfinite(velocity).all(-1) & np.asarray(valid, bool)
    motion = np.where(known[..., None], velocity, 0.0)
    speed = np.linalg.norm(motion, axis=-1)
    agreement = np.einsum("...k,...k->...", np.asarray(forward, dtype=np.float64), motion)
    return bool(config.enabled) & known & (speed > config.min_speed) & (agreement < config.max_agreement * speed)


LEG_LANDMARKS: tuple[int, ...] = (23, 24, 25, 26, 27, 28)
"""BlazePose's hips, knees and ankles."""


def legs_seen(image: np.ndarray, min_visibility: float) -> np.ndarray:
    """``(...)`` bool: every hip, knee and ankle of BlazePose's landmarks ``image (..., 33, 5)`` has
    visibility (column 3) at least ``min_visibility``."""
    return np.asarray(image)[..., list(LEG_LANDMARKS), 3].min(-1) >= min_visibility


__all__ = ["LEG_LANDMARKS", "legs_seen", "BLAZEPOSE_MIRROR", "FacingConfig", "mirrored", "body_forward", "root_velocity", "facing_flips"]
