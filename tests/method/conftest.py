"""A tiny two-shot scene with noise-free simulated inputs, shared by the method's tests."""

import dataclasses

import numpy as np
import pytest
import torch

from multithumbs.geometry import Similarity, umeyama, unproject
from multithumbs.synth.perception import NO_NOISE, simulate_perception
from multithumbs.synth.scene import SceneConfig, synthesize
from multithumbs.synth.simulated_geometry import (SharedSpaceNoise, TrajectoryNoise, simulate_camera_trajectory,
                                                  simulate_shared_space)

CLEAN_SPACE = SharedSpaceNoise(depth_sigma=0, rotation_deg=0, translation_sigma=0)
CLEAN_TRACKING = TrajectoryNoise(rotation_drift_deg=0, translation_drift=0)


@dataclasses.dataclass(frozen=True)
class TinyScene:
    video: object
    shots: object
    tracks: list
    spaces: list
    trajectories: list
    space_from_world: list  # per cut: the exact similarity world -> shared space


def _space_from_world(video, space, cut_index):
    """The similarity that carried the true world into a noise-free shared space (from its frame-0 points)."""
    world = video.truth.world
    f = int(world.cut_frames[cut_index]) - 1
    sel = space.observed[0]
    pix = space.pixels[0, sel]
    depth = video.boundary_depth[cut_index, 0][pix[:, 1].astype(int), pix[:, 0].astype(int)].astype(float)
    world_points = (unproject(pix, depth, world.K[f]) - world.t[f]) @ world.R[f]
    return umeyama(world_points, space.points[sel])


@pytest.fixture(scope="session")
def tiny(body):
    config = SceneConfig(num_people=2, num_shots=2, num_frames=10, seed=31, image_size=(240, 426),
                         cut_angle_deg=35, moving_cameras=True)
    video = synthesize(config, body)
    shots = video.truth.world.shots()
    tracks = simulate_perception(video, body, NO_NOISE)
    spaces = [simulate_shared_space(video, c, CLEAN_SPACE) for c in range(len(shots.cut_frames))]
    trajectories = [simulate_camera_trajectory(video, k, CLEAN_TRACKING) for k in range(shots.num_shots)]
    frames = [_space_from_world(video, s, c) for c, s in enumerate(spaces)]
    return TinyScene(video, shots, tracks, spaces, trajectories, frames)


def metric_frame(space_from_world: Similarity) -> Similarity:
    """The rigid part of world -> shared space: the space brought to metric scale."""
    s, R, t = space_from_world.numpy()
    return Similarity.from_numpy(1.0, R, t / s)


def apply(sim: Similarity, points: np.ndarray) -> np.ndarray:
    return sim.apply(torch.from_numpy(np.asarray(points, dtype=np.float64))).numpy()
