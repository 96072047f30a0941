"""Small synthetic scenes shared by the scene tests (rendered once per session)."""

from dataclasses import dataclass

import numpy as np
import pytest

from multithumbs.synth.scene import SceneConfig, SyntheticVideo, synthesize


@dataclass(frozen=True)
class Clip:
    video: SyntheticVideo

    @property
    def world(self):
        return self.video.truth.world

    def person_masks(self, frame: int) -> np.ndarray:
        """``(P, H, W)`` true masks of every person at a frame."""
        return np.stack([self.video.instance[frame] == p for p in range(self.world.num_people)])


@pytest.fixture(scope="session")
def static_clip(body) -> Clip:
    """Two static shots, 36 frames, 320x180, cut at 40 degrees."""
    config = SceneConfig(num_people=2, num_shots=2, num_frames=36, seed=7, image_size=(180, 320), cut_angle_deg=40)
    return Clip(synthesize(config, body))


@pytest.fixture(scope="session")
def moving_clip(body) -> Clip:
    """Two dollying shots, 48 frames, 426x240, cut at 30 degrees; a fast dolly so 24 frames have parallax."""
    config = SceneConfig(num_people=2, num_shots=2, num_frames=48, seed=8, image_size=(240, 426), cut_angle_deg=30,
                         moving_cameras=True, dolly_speed=1.2)
    return Clip(synthesize(config, body))


def rotation_error_deg(R_a: np.ndarray, R_b: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip((np.trace(R_a.T @ R_b) - 1) / 2, -1, 1))))


def relative(R: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Camera 1 from camera 0 of ``R (2, 3, 3)``, ``t (2, 3)``."""
    R_rel = R[1] @ R[0].T
    return R_rel, t[1] - R_rel @ t[0]


def direction_error_deg(a: np.ndarray, b: np.ndarray) -> float:
    cos = np.dot(a, b) / (np.linalg.norm(a) * np.linalg.norm(b))
    return float(np.degrees(np.arccos(np.clip(cos, -1, 1))))
