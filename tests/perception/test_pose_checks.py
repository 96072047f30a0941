"""The tracker's checks on one reading (:mod:`multithumbs.perception.pose_checks`)."""

import numpy as np
import pytest

from multithumbs.perception import blazepose as bp
from multithumbs.perception.pose_checks import plausible
from multithumbs.perception.pose_tracking import TrackerConfig


def reading(roll_deg: float) -> bp.Landmarks:
    """A 160 px tall pose in a 200 px square whose auxiliary landmarks (hip centre 33, head top 34) turn
    its own square ``roll_deg`` from upright (clockwise on screen)."""
    points = np.zeros((39, 5))
    points[:33, 0], points[:33, 1] = 200.0, np.linspace(100, 260, 33)
    points[:33, 3:] = 1.0
    angle = np.deg2rad(roll_deg)
    hip = np.array([200.0, 200.0])
    points[33, :2] = hip
    points[34, :2] = hip + 80.0 * np.array([np.sin(angle), -np.cos(angle)])  # up is -v on screen
    return bp.Landmarks(1.0, points, np.zeros((33, 3)), np.zeros((0, 0), np.float32),
                        bp.Roi(hip, 200.0, 0.0))


@pytest.mark.parametrize("roll_deg, expected", [(0, True), (30, True), (-80, True), (120, False), (180, False),
                                                 (-135, False)])
def test_a_pose_read_head_down_is_not_plausible(roll_deg, expected):
    turn = bp.roi_from_landmarks(reading(roll_deg)).rotation - np.deg2rad(roll_deg)
    assert np.angle(np.exp(1j * turn)) == pytest.approx(0.0, abs=1e-9)  # the fixture turns as it says
    assert plausible(reading(roll_deg), TrackerConfig()) is expected


def test_max_roll_is_the_limit():
    assert plausible(reading(120), TrackerConfig(max_roll=np.deg2rad(130)))
    assert not plausible(reading(60), TrackerConfig(max_roll=np.deg2rad(50)))
