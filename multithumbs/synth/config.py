"""The synthetic scene's settings (:class:`SceneConfig`, :class:`MotionConfig`) and their JSON form.

No torch, no scipy: a flow keys its artifacts on a scene's JSON and a re-run served from the store reads
no more than this (:mod:`multithumbs.synth.scene` renders, and re-exports these names).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from multithumbs.errors import InputError


@dataclass(frozen=True)
class MotionConfig:
    """How people move.

    Attributes:
        walk_speed: mean walking speed (m/s).
        walk_speed_spread: per-person spread of the walking speed (m/s).
        stride_length: length of a full gait cycle, two steps (m).
        turn_rate: maximum turning speed (rad/s).
        stand_probability: chance that a person pauses at a waypoint instead of walking on.
        stand_seconds: (min, max) duration of a pause (s).
        gesture_probability: chance that a pause includes waving or pointing.
        region: half-extents (x, y) of the floor area people walk in, centred on the origin (m).
    """

    walk_speed: float = 1.1
    walk_speed_spread: float = 0.15
    stride_length: float = 1.35
    turn_rate: float = np.pi
    stand_probability: float = 0.35
    stand_seconds: tuple[float, float] = (0.6, 2.0)
    gesture_probability: float = 0.5
    region: tuple[float, float] = (2.0, 1.6)


@dataclass(frozen=True)
class SceneConfig:
    """A synthetic multi-shot scene. Every random choice follows from ``seed``.

    Attributes:
        num_people: people in the scene (1..8).
        num_shots: shots in the video; shot ``k`` is filmed by camera ``k``.
        num_frames: frames in the video.
        seed: seed of every random choice.
        cut_angle_deg: yaw between consecutive shots' cameras about the scene centre (degrees).
        moving_cameras: per shot, whether its camera dollies sideways; one bool applies to all shots.
        image_size: ``(H, W)`` in pixels.
        fps: frames per second.
        horizontal_fov_deg: horizontal field of view of every camera (degrees).
        camera_distance: distance of the cameras from the scene centre (m).
        camera_height: (min, max) height of the cameras above the floor (m).
        dolly_speed: sideways speed of a moving camera (m/s).
        only_in_one_shot: persons (indices) present in one shot only, the shot given: ``((person, shot),)``.
        absent_in_shots: persons (indices) out of the scene during one shot: ``((person, shot),)``. With
            ``((0, 1),)`` person 0 is seen in shots 0 and 2 and not in shot 1 (A-B-A).
        dialogue: a conversation cut as shot/reverse-shot (:mod:`multithumbs.synth.dialogue`): people stand
            in a group facing each other; the shots alternate between two cameras ``cut_angle_deg`` apart
            about the group's centre, ``camera_distance`` from it, each over the shoulder of the person on
            its side (who is near it, partly out of frame, seen from behind) and aimed at the others.
        dressed_alike: pairs of persons dressed alike: the same neutral-grey uniform, skin, shaven head
            and build.
        crossing_pair: two persons whose paths cross at the scene centre at the first cut, or None. When one
            of them walks in ``abreast_pair``, the other walks against the pair instead and passes that
            person on the outside (0.6 m beside their line) at the first cut.
        abreast_pair: two persons walking side by side through the first cut, or None: the same heading and
            speed on parallel lines ``abreast_spacing`` apart, their midpoint passing just beyond the scene
            centre at the cut, walking away from the cut's cameras 30 degrees off their mean view direction
            (20 or 40 where one would hide the other). Both then show the same side of the body under the
            same light in both boundary frames, so (dressed alike) only where they are tells them apart.
            Everybody else walks at random but keeps out of their way.
        abreast_spacing: distance between the lines of ``abreast_pair`` (m).
        room_size: (width, depth, height) of the room (m).
        motion: how people move.
        name: the scene's name in a suite, or "".
    """

    num_people: int = 3
    num_shots: int = 2
    num_frames: int = 120
    seed: int = 0
    cut_angle_deg: float = 45.0
    moving_cameras: bool | tuple[bool, ...] = False
    image_size: tuple[int, int] = (360, 640)
    fps: float = 30.0
    horizontal_fov_deg: float = 62.0
    camera_distance: float = 3.4
    camera_height: tuple[float, float] = (1.5, 2.1)
    dolly_speed: float = 0.3
    only_in_one_shot: tuple[tuple[int, int], ...] = ()
    absent_in_shots: tuple[tuple[int, int], ...] = ()
    dialogue: bool = False
    dressed_alike: tuple[tuple[int, int], ...] = ()
    crossing_pair: tuple[int, int] | None = None
    abreast_pair: tuple[int, int] | None = None
    abreast_spacing: float = 1.2
    room_size: tuple[float, float, float] = (9.0, 8.0, 3.0)
    motion: MotionConfig = field(default_factory=MotionConfig)
    name: str = ""

    def __post_init__(self) -> None:
        if not 1 <= self.num_people <= 8:
            raise InputError(f"people: need 1 to 8 people, got {self.num_people}")
        if self.num_shots < 1:
            raise InputError(f"shots: need at least one shot, got {self.num_shots}")
        if self.num_frames < 2 * self.num_shots:
            raise InputError(f"frames: {self.num_frames} frames cannot hold {self.num_shots} shots "
                             f"(each shot needs at least 2 frames)")
        if not 0 <= self.cut_angle_deg <= 180:
            raise InputError(f"cut-angle: must be within [0, 180] degrees, got {self.cut_angle_deg}")
        h, w = self.image_size
        if h < 32 or w < 32:
            raise InputError(f"image size: at least 32x32 pixels, got {h}x{w}")
        if not self.fps > 0:
            raise InputError(f"fps: must be positive, got {self.fps}")
        moving = self.moving_cameras
        if not isinstance(moving, bool) and len(moving) != self.num_shots:
            raise InputError(f"moving_cameras: one flag per shot ({self.num_shots}), got {len(moving)}")
        pairs = [*self.dressed_alike, *[pair for pair in (self.crossing_pair, self.abreast_pair) if pair is not None]]
        people = [p for pair in pairs for p in pair] + [p for p, _ in (*self.only_in_one_shot, *self.absent_in_shots)]
        if any(not 0 <= p < self.num_people for p in people):
            raise InputError(f"scene {self.name or 'config'}: a person index is out of range for "
                             f"{self.num_people} people")
        if any(len(pair) != 2 or pair[0] == pair[1] for pair in pairs):
            raise InputError(f"scene {self.name or 'config'}: a pair must name two different persons")
        if self.abreast_pair is not None:
            if self.crossing_pair is not None and set(self.crossing_pair) == set(self.abreast_pair):
                raise InputError(f"scene {self.name or 'config'}: the abreast pair cannot also be the crossing pair")
            if not 0.6 <= self.abreast_spacing <= 3.0:
                raise InputError(f"abreast_spacing: must be within [0.6, 3.0] m, got {self.abreast_spacing}")
        if any(not 0 <= s < self.num_shots for _, s in (*self.only_in_one_shot, *self.absent_in_shots)):
            raise InputError(f"scene {self.name or 'config'}: a shot index is out of range for "
                             f"{self.num_shots} shots")
        if self.dialogue and (not 2 <= self.num_people <= 4 or self.crossing_pair is not None or self.abreast_pair is not None):
            raise InputError(f"scene {self.name or 'config'}: a dialogue holds 2 to 4 standing people "
                             f"(no crossing or abreast pair)")

    def camera_is_moving(self, shot: int) -> bool:
        moving = self.moving_cameras
        return bool(moving) if isinstance(moving, bool) else bool(moving[shot])


def config_to_json(config: SceneConfig) -> dict:
    out = dataclasses.asdict(config)
    out["motion"] = dataclasses.asdict(config.motion)
    return out


def config_from_json(data: dict) -> SceneConfig:
    """Inverse of :func:`config_to_json`; missing fields take their defaults, unknown fields are an error."""
    defaults = config_to_json(SceneConfig())
    unknown = sorted(set(data) - set(defaults))
    if unknown:
        raise InputError(f"scene config: unknown field {unknown[0]!r}")
    data = {**defaults, **data, "motion": {**defaults["motion"], **data.get("motion", {})}}
    data["motion"] = MotionConfig(**{k: tuple(v) if isinstance(v, list) else v for k, v in data["motion"].items()})
    for key in ("image_size", "camera_height", "room_size"):
        data[key] = tuple(data[key])
    data["only_in_one_shot"] = tuple(tuple(x) for x in data["only_in_one_shot"])
    data["absent_in_shots"] = tuple(tuple(x) for x in data["absent_in_shots"])
    data["dressed_alike"] = tuple(tuple(x) for x in data["dressed_alike"])
    for key in ("crossing_pair", "abreast_pair"):
        if data[key] is not None:
            data[key] = tuple(data[key])
    if isinstance(data["moving_cameras"], list):
        data["moving_cameras"] = tuple(data["moving_cameras"])
    return SceneConfig(**data)
