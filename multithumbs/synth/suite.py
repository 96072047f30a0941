"""Named suites of synthetic scenes. ``standard`` is the benchmark every issue reports on; ``dialogue`` is
shot/reverse-shot conversations with cuts of 120-180 degrees (:mod:`multithumbs.synth.dialogue`).

The standard suite covers 2-4 people, 2-3 shots, cut angles from 20 to 90 degrees, static and moving
cameras, a person present in one shot only, people crossing paths at a cut, and two people dressed alike who
walk side by side through the cut (so both show the same view at it: only where they are tells them apart;
in s12 a third person passes them at the cut).
"""

from __future__ import annotations

from multithumbs.errors import InputError
from multithumbs.synth.config import SceneConfig

_STANDARD: tuple[SceneConfig, ...] = (
    SceneConfig(name="s01_two_people_20deg", num_people=2, num_shots=2, cut_angle_deg=20, seed=101),
    SceneConfig(name="s02_three_people_30deg", num_people=3, num_shots=2, cut_angle_deg=30, seed=102),
    SceneConfig(name="s03_four_people_45deg", num_people=4, num_shots=2, cut_angle_deg=45, seed=103),
    SceneConfig(name="s04_three_people_60deg_moving", num_people=3, num_shots=2, cut_angle_deg=60, seed=104,
                moving_cameras=True),
    SceneConfig(name="s05_two_people_90deg", num_people=2, num_shots=2, cut_angle_deg=90, seed=105),
    SceneConfig(name="s06_three_shots_40deg", num_people=3, num_shots=3, cut_angle_deg=40, seed=106),
    SceneConfig(name="s07_one_shot_person", num_people=3, num_shots=2, cut_angle_deg=35, seed=107,
                only_in_one_shot=((2, 0),)),
    SceneConfig(name="s08_dressed_alike", num_people=3, num_shots=2, cut_angle_deg=30, seed=108,
                dressed_alike=((0, 1),), abreast_pair=(0, 1)),
    SceneConfig(name="s09_crossing_at_cut", num_people=2, num_shots=2, cut_angle_deg=45, seed=109,
                crossing_pair=(0, 1)),
    SceneConfig(name="s10_four_people_75deg_moving", num_people=4, num_shots=2, cut_angle_deg=75, seed=110,
                moving_cameras=(True, False)),
    SceneConfig(name="s11_three_shots_moving_enter", num_people=4, num_shots=3, cut_angle_deg=50, seed=111,
                moving_cameras=(False, True, False), only_in_one_shot=((3, 2),)),
    SceneConfig(name="s12_alike_crossing_25deg", num_people=3, num_shots=2, cut_angle_deg=25, seed=112,
                dressed_alike=((0, 1),), abreast_pair=(0, 1), crossing_pair=(1, 2)),
)

# Dialogue: shot/reverse-shot, over the shoulder (the near person seen from behind, cut by the frame's edge),
# the boundary frames sharing no background. d04: person 0 leaves for shot 1 and is back in shot 2 (A-B-A).
_DIALOGUE_VIEW = dict(dialogue=True, camera_distance=2.0, camera_height=(1.45, 1.65))
_DIALOGUE: tuple[SceneConfig, ...] = (
    SceneConfig(name="d01_dialogue_120deg", num_people=2, num_shots=2, cut_angle_deg=120, seed=201, **_DIALOGUE_VIEW),
    SceneConfig(name="d02_dialogue_150deg_three", num_people=3, num_shots=2, cut_angle_deg=150, seed=202,
                **_DIALOGUE_VIEW),
    SceneConfig(name="d03_dialogue_180deg", num_people=2, num_shots=3, cut_angle_deg=180, seed=203, **_DIALOGUE_VIEW),
    SceneConfig(name="d04_dialogue_180deg_return", num_people=3, num_shots=3, cut_angle_deg=180, seed=204,
                absent_in_shots=((0, 1),), **_DIALOGUE_VIEW),
)

SUITES: dict[str, tuple[SceneConfig, ...]] = {"standard": _STANDARD, "dialogue": _DIALOGUE}


def suite(name: str) -> tuple[SceneConfig, ...]:
    """The scene configs of a named suite."""
    if name not in SUITES:
        raise InputError(f"suite {name!r}: unknown; known suites: {', '.join(sorted(SUITES))}")
    return SUITES[name]


def suite_scene(suite_name: str, scene_name: str) -> SceneConfig:
    """One scene of a suite by name."""
    for config in suite(suite_name):
        if config.name == scene_name:
            return config
    names = ", ".join(c.name for c in suite(suite_name))
    raise InputError(f"scene {scene_name!r}: not in suite {suite_name!r} ({names})")
