"""Procedural human motion in a z-up world: walking paths, turning, standing, gesturing.

Poses are SMPL axis-angle. The body frame is SMPL's (+y up, facing +z, left +x); a person standing
upright facing world direction ``(cos h, sin h, 0)`` has ``global_orient = Rz(h) @ BODY_TO_WORLD``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import gaussian_filter1d
from scipy.spatial.transform import Rotation

from multithumbs.synth.config import MotionConfig  # noqa: F401  (defined there without scipy; re-exported)

# Body +x (left) -> world +y, body +y (up) -> world +z, body +z (forward) -> world +x.
BODY_TO_WORLD = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])

_HIP = {"left": 0, "right": 1}          # body_pose index = SMPL joint index - 1
_KNEE = {"left": 3, "right": 4}
_ANKLE = {"left": 6, "right": 7}
_SHOULDER = {"left": 15, "right": 16}
_ELBOW = {"left": 17, "right": 18}
_SPINE = (2, 5, 8)
_NECK, _HEAD = 11, 14


@dataclass(frozen=True)
class PersonMotion:
    """One person's motion over the whole video.

    Attributes:
        position: ``(T, 2)`` floor position of the pelvis (m).
        heading: ``(T,)`` facing direction angle about world +z (rad).
        gait_phase: ``(T,)`` gait cycle phase (rad).
        gait_amount: ``(T,)`` 0 standing ... 1 full walking swing.
        gesture: ``(T,)`` 0 none, 1 waving (right arm), 2 pointing (left arm).
        gesture_phase: ``(T,)`` time within the gesture (s).
    """

    position: np.ndarray
    heading: np.ndarray
    gait_phase: np.ndarray
    gait_amount: np.ndarray
    gesture: np.ndarray
    gesture_phase: np.ndarray


def _wrap(angle: np.ndarray | float) -> np.ndarray | float:
    return (angle + np.pi) % (2 * np.pi) - np.pi


def simulate_walk(start: np.ndarray, waypoints: list[np.ndarray], num_frames: int, fps: float,
                  rng: np.random.Generator, config: MotionConfig = MotionConfig(),
                  speed: float | None = None, start_heading: float | None = None,
                  allow_pauses: bool = True) -> PersonMotion:
    """Walk through ``waypoints`` (cycling through fresh random ones when exhausted), pausing at some.

    Args:
        start: ``(2,)`` initial floor position.
        waypoints: floor targets visited in order; afterwards targets are drawn in ``config.region``.
        speed: walking speed (m/s); drawn around ``config.walk_speed`` when None.
        start_heading: initial facing (rad); towards the first target when None.
        allow_pauses: False walks without stopping (used for scripted crossings).
    """
    dt = 1.0 / fps
    speed = speed if speed is not None else config.walk_speed + config.walk_speed_spread * rng.standard_normal()
    speed = float(np.clip(speed, 0.5, 1.8))
    queue = [np.asarray(w, float) for w in waypoints]

    def next_target() -> np.ndarray:
        if queue:
            return queue.pop(0)
        return rng.uniform(-1, 1, 2) * np.asarray(config.region)

    pos = np.asarray(start, float).copy()
    target = next_target()
    heading = float(np.arctan2(*(target - pos)[::-1])) if start_heading is None else start_heading
    out = {k: np.zeros(num_frames) for k in ("heading", "phase", "amount", "gesture", "gesture_phase")}
    positions = np.zeros((num_frames, 2))
    phase, amount, pause_left, gesture, gesture_time = rng.uniform(0, 2 * np.pi), 0.0, 0.0, 0, 0.0
    for f in range(num_frames):
        if pause_left > 0:
            pause_left -= dt
            gesture_time += dt
            amount = max(0.0, amount - 4 * dt)  # settle the legs within a quarter second
            if pause_left <= 0:
                gesture = 0
        else:
            if np.linalg.norm(target - pos) < 0.15:
                if allow_pauses and rng.random() < config.stand_probability:
                    pause_left = rng.uniform(*config.stand_seconds)
                    gesture = int(rng.integers(1, 3)) if rng.random() < config.gesture_probability else 0
                    gesture_time = 0.0
                target = next_target()
            if pause_left <= 0:
                to_target = target - pos
                desired = np.arctan2(to_target[1], to_target[0])
                heading += float(np.clip(_wrap(desired - heading), -config.turn_rate * dt, config.turn_rate * dt))
                # Slow down while turning sharply, as people do.
                step = speed * dt * max(0.2, np.cos(_wrap(desired - heading)))
                pos = pos + step * np.array([np.cos(heading), np.sin(heading)])
                phase += 2 * np.pi * step / config.stride_length
                amount = min(1.0, amount + 4 * dt)
        positions[f] = pos
        out["heading"][f], out["phase"][f], out["amount"][f] = heading, phase, amount
        out["gesture"][f], out["gesture_phase"][f] = gesture, gesture_time
    return PersonMotion(positions, out["heading"], out["phase"], out["amount"],
                        out["gesture"].astype(np.int64), out["gesture_phase"])


def straight_walk(through: np.ndarray, heading: float, at_time: float, num_frames: int, fps: float,
                  speed: float, rng: np.random.Generator, config: MotionConfig = MotionConfig(),
                  path: tuple[float, float] = (-np.inf, np.inf)) -> PersonMotion:
    """Walk a straight line at constant speed and heading, passing ``through`` at ``at_time``.

    The person stands at the ends of ``path`` (signed distance along the heading from ``through``, m)
    before setting off and after arriving, legs settling as in :func:`simulate_walk`.

    Args:
        through: ``(2,)`` floor point on the line.
        heading: walking direction about world +z (rad), kept throughout.
        at_time: time (s) at which the person is at ``through`` (when it lies within ``path``).
        speed: walking speed (m/s).
        rng: draws the initial gait phase.
        config: gives the stride length.
        path: ``(min, max)`` stretch of the line walked; must contain 0 for ``through`` to be reached.
    """
    direction = np.array([np.cos(heading), np.sin(heading)])
    t_axis = np.arange(num_frames) / fps
    along = np.clip(speed * (t_axis - at_time), *path)
    position = np.asarray(through, float)[None] + along[:, None] * direction[None]
    step = np.abs(np.diff(along, prepend=along[0]))
    moving = step > 1e-9
    amount = np.zeros(num_frames)
    for f in range(1, num_frames):  # legs swing up and settle within a quarter second, as in simulate_walk
        amount[f] = min(1.0, amount[f - 1] + 4 / fps) if moving[f] else max(0.0, amount[f - 1] - 4 / fps)
    phase = rng.uniform(0, 2 * np.pi) + 2 * np.pi * np.cumsum(step) / config.stride_length
    zeros = np.zeros(num_frames)
    return PersonMotion(position, np.full(num_frames, float(heading)), phase, amount, zeros.astype(np.int64),
                        zeros.copy())


def walk_abreast(through: np.ndarray, heading: float, at_time: float, spacing: float, num_frames: int,
                 fps: float, rng: np.random.Generator, config: MotionConfig = MotionConfig(),
                 speed: float | None = None, path: tuple[float, float] = (-np.inf, np.inf)
                 ) -> tuple[PersonMotion, PersonMotion]:
    """Two people walking side by side: the same heading and speed on parallel lines ``spacing`` apart.

    Their midpoint passes ``through`` at ``at_time``; they set off and stop together (``path`` as in
    :func:`straight_walk`, for the midpoint). Only the gait phase differs between them (drawn per person):
    from any viewpoint both show the same side of the body under the same light.

    Returns:
        the person on the left of the heading, then the one on the right.
    """
    speed = speed if speed is not None else config.walk_speed + config.walk_speed_spread * rng.standard_normal()
    speed = float(np.clip(speed, 0.5, 1.8))
    left = np.array([-np.sin(heading), np.cos(heading)])
    through = np.asarray(through, float)
    return tuple(straight_walk(through + side * 0.5 * spacing * left, heading, at_time, num_frames, fps, speed,
                               rng, config, path) for side in (1.0, -1.0))


def _rot(axis: str, angle: np.ndarray) -> np.ndarray:
    """``(T, 3, 3)`` rotations about a body axis."""
    return Rotation.from_euler(axis, np.asarray(angle, float)[..., None]).as_matrix()


def motion_to_smpl(motion: PersonMotion) -> tuple[np.ndarray, np.ndarray]:
    """SMPL ``global_orient (T, 3)`` and ``body_pose (T, 23, 3)`` of a motion (axis-angle).

    Gait: hips swing about the body x axis, knees flex, ankles follow, arms swing opposite to the
    legs; the spine counter-rotates slightly. Gestures: waving raises the right arm and swings the
    forearm; pointing lifts the left arm forward.
    """
    t_count = motion.heading.shape[0]
    phase, amount = motion.gait_phase, motion.gait_amount
    pose = np.tile(np.eye(3), (t_count, 23, 1, 1))
    sin = np.sin(phase)
    for side, sgn in (("left", 1.0), ("right", -1.0)):
        s = sgn * sin
        # Negative rotation about +x swings a leg forward (+z) in SMPL's body frame.
        pose[:, _HIP[side]] = _rot("x", -np.deg2rad(24) * s * amount - np.deg2rad(4) * amount)
        knee = np.deg2rad(8) + np.deg2rad(32) * np.clip(np.sin(phase + sgn * np.pi / 2 + np.pi), 0, None)
        pose[:, _KNEE[side]] = _rot("x", (knee * amount) + np.deg2rad(3))
        pose[:, _ANKLE[side]] = _rot("x", -np.deg2rad(8) * s * amount)
        # Arms hang at the sides (rotation about z) and swing opposite to the same-side leg.
        down = np.deg2rad(-72) if side == "left" else np.deg2rad(72)
        swing = np.deg2rad(20) * s * amount
        pose[:, _SHOULDER[side]] = _rot("x", swing) @ _rot("z", np.full(t_count, down))
        elbow_axis_sign = -1.0 if side == "left" else 1.0
        pose[:, _ELBOW[side]] = _rot("y", elbow_axis_sign * (np.deg2rad(12) + np.deg2rad(10) * amount * (1 + s) / 2))
    twist = np.deg2rad(4) * sin * amount
    for j in _SPINE:
        pose[:, j] = _rot("y", -twist / len(_SPINE))
    pose[:, _HEAD] = _rot("y", np.deg2rad(10) * np.sin(0.7 * motion.gesture_phase) * (motion.gesture > 0))

    wave = motion.gesture == 1
    if wave.any():
        g = motion.gesture_phase[wave]
        lift = np.clip(g / 0.4, 0, 1)  # raise the arm over 0.4 s
        pose[wave, _SHOULDER["right"]] = _rot("z", np.deg2rad(72) - lift * np.deg2rad(140))
        pose[wave, _ELBOW["right"]] = _rot("y", lift * (np.deg2rad(60) + np.deg2rad(35) * np.sin(2 * np.pi * 1.5 * g)))
    point = motion.gesture == 2
    if point.any():
        g = motion.gesture_phase[point]
        lift = np.clip(g / 0.5, 0, 1)
        pose[point, _SHOULDER["left"]] = _rot("y", -lift * np.deg2rad(80)) @ _rot("z", np.full(g.shape, np.deg2rad(-72)) * (1 - 0.3 * lift))
        pose[point, _ELBOW["left"]] = _rot("y", -np.deg2rad(8) * np.ones_like(g))

    heading_rot = _rot("z", motion.heading)
    global_orient = Rotation.from_matrix(heading_rot @ BODY_TO_WORLD).as_rotvec()
    body_pose = Rotation.from_matrix(pose.reshape(-1, 3, 3)).as_rotvec().reshape(t_count, 23, 3)
    return global_orient, body_pose


def stand_and_talk(position: np.ndarray, facing: np.ndarray, num_frames: int, fps: float,
                   rng: np.random.Generator, config: MotionConfig = MotionConfig()) -> PersonMotion:
    """A person standing in a conversation: in place at ``position (2,)``, turned towards ``facing (2,)``.

    The body sways a few centimetres and turns slowly by up to ~10 degrees (smoothed noise); now and then a
    gesture (waving or pointing, ``config.stand_seconds`` long) accompanies speech, with probability
    ``config.gesture_probability`` per pause-length window. Legs stay still (no gait).
    """
    t_axis = np.arange(num_frames) / fps
    smooth = max(1.0, 0.8 * fps)  # motion correlated over ~0.8 s
    sway = gaussian_filter1d(rng.standard_normal((num_frames, 3)), smooth, axis=0, mode="nearest")
    sway /= max(float(sway.std()), 1e-9)
    to_face = np.asarray(facing, float) - np.asarray(position, float)
    heading = float(np.arctan2(to_face[1], to_face[0])) + np.deg2rad(5.0) * sway[:, 2]
    pos = np.asarray(position, float)[None] + 0.02 * sway[:, :2]
    gesture = np.zeros(num_frames, np.int64)
    gesture_phase = np.zeros(num_frames)
    start = float(rng.uniform(0, config.stand_seconds[1]))
    while start < t_axis[-1]:
        length = float(rng.uniform(*config.stand_seconds))
        if rng.random() < config.gesture_probability:
            inside = (t_axis >= start) & (t_axis < start + length)
            gesture[inside] = int(rng.integers(1, 3))
            gesture_phase[inside] = t_axis[inside] - start
        start += length + float(rng.uniform(*config.stand_seconds))
    zeros = np.zeros(num_frames)
    return PersonMotion(pos, heading, rng.uniform(0, 2 * np.pi) + zeros, zeros.copy(), gesture, gesture_phase)
