"""A conversation cut as shot/reverse-shot: where the people stand and where the cameras are.

The people stand in a group about the scene centre, each facing the others (:func:`stand_and_talk`).
Two of them face each other across the cut: person 0 stands on camera side 0 (azimuth ``a0`` about the
centre) and person 1 on side 1 (``a0 ± cut_angle``); a third and fourth listen from the far side of the
group. Shot ``k`` is filmed from side ``k mod 2``: the camera stands behind the person on its side, a
little to the side of them ("over the shoulder"), and looks at the people of the other side. The near
person is then close to the camera, seen from behind and cut by the frame's edge, the far person is seen
from the front, and at 150-180 degrees the two boundary frames share almost no background: the case films
and sitcoms cut most, and the one the scene's geometry cannot resolve (docs/RESULTS.md, dialogue cuts).
"""

from __future__ import annotations

import numpy as np

from multithumbs.geometry import intrinsics_from_fov, look_at
from multithumbs.synth.config import SceneConfig
from multithumbs.synth.motion import PersonMotion, stand_and_talk

GROUP_RADIUS = 0.75
"""Distance (m) of each person from the group's centre."""
SHOULDER_OFFSET = 0.65
"""Sideways offset (m) of a camera from the line through the centre and its side's azimuth: with the
cameras ``camera_distance`` from the centre, the near person's body and the far person's stay apart in
the image (about 14 degrees between them), as an over-the-shoulder shot frames them."""
AIM_HEIGHT = 1.15
"""Height (m) of the point a camera looks at (the far people's chests)."""
CAMERA_JITTER_DEG = 4.0
"""A shot's camera is ``side azimuth ± this`` (degrees): a returning side is not the identical camera."""


def _unit(angle: float) -> np.ndarray:
    return np.array([np.cos(angle), np.sin(angle)])


def people_positions(config: SceneConfig, a0: float, direction: float) -> np.ndarray:
    """``(P, 2)`` floor positions: persons 0 and 1 on the two camera sides, the others across the group."""
    a1 = a0 + direction * np.deg2rad(config.cut_angle_deg)
    far = a0 + direction * np.deg2rad(config.cut_angle_deg) / 2 + np.pi
    angles = [a0, a1, far, far + np.deg2rad(40.0)][:config.num_people]
    if config.num_people == 4:
        angles[2] = far - np.deg2rad(20.0)
        angles[3] = far + np.deg2rad(20.0)
    return np.stack([GROUP_RADIUS * _unit(a) for a in angles])


def dialogue_layout(config: SceneConfig, rng: np.random.Generator, presence: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, tuple[PersonMotion, ...]]:
    """The cameras and motions of a dialogue scene (module docstring).

    Args:
        rng: the scene's random stream.
        presence: ``(P, T)`` bool, who is in the scene in each frame (a shot's camera aims at those present).
    Returns:
        ``K (S, 3, 3)``, ``R (S, T, 3, 3)``, ``t (S, T, 3)`` (static cameras) and one motion per person.
    """
    from multithumbs.synth.scene import config_shot_mask

    h, w = config.image_size
    K = intrinsics_from_fov(w, h, config.horizontal_fov_deg)
    a0 = rng.uniform(0, 2 * np.pi)
    direction = rng.choice([-1.0, 1.0])
    positions = people_positions(config, a0, direction)
    sides = (a0, a0 + direction * np.deg2rad(config.cut_angle_deg))
    # Over whose shoulder: to the side of the listeners (person 2), so the near person does not hide them.
    listeners = positions[2:].mean(axis=0) if config.num_people > 2 else None
    Rs, ts = [], []
    for k in range(config.num_shots):
        side = k % 2
        az = sides[side] + np.deg2rad(rng.uniform(-CAMERA_JITTER_DEG, CAMERA_JITTER_DEG))
        radial, tangent = _unit(az), _unit(az + np.pi / 2)
        sign = float(np.sign(tangent @ listeners)) if listeners is not None and abs(tangent @ listeners) > 1e-6 \
            else float(rng.choice([-1.0, 1.0]))
        eye_xy = config.camera_distance * radial + sign * SHOULDER_OFFSET * tangent
        height = rng.uniform(*config.camera_height)
        frames = config_shot_mask(config, k)
        # Aim at the people of the other side present in the shot (the near person is never aimed at).
        others = [p for p in range(config.num_people) if p != side and presence[p, frames].any()]
        others = others or [1 - side]
        target_xy = positions[others].mean(axis=0)
        eye = np.tile(np.append(eye_xy, height), (config.num_frames, 1))
        target = np.tile(np.append(target_xy, AIM_HEIGHT), (config.num_frames, 1))
        R, t = look_at(eye, target)
        Rs.append(R)
        ts.append(t)
    centroid = positions.mean(axis=0)
    motions = []
    for p in range(config.num_people):
        # Speakers 0 and 1 face each other; the others face the group's centre.
        facing = positions[1 - p] if p < 2 else centroid
        motions.append(stand_and_talk(positions[p], facing, config.num_frames, config.fps, rng, config.motion))
    return np.repeat(K[None], config.num_shots, 0), np.stack(Rs), np.stack(ts), tuple(motions)
