"""Fixtures of the export and viz tests: a small synthetic two-shot scene written to disk, and rigid copies.

``small_scene`` is session-scoped (rendered once, about a second); tests must not modify its files.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from multithumbs.synth.files import write_synthetic
from multithumbs.synth.scene import SceneConfig, synthesize
from multithumbs.types import WorldResult


@pytest.fixture(scope="session")
def small_scene(body, tmp_path_factory) -> SimpleNamespace:
    """Two people, two shots, 12 frames at 200x120: ``video`` (SyntheticVideo), ``dir``, ``video_path``,
    ``truth_path``, ``truth`` (GroundTruth), ``world`` (its WorldResult)."""
    video = synthesize(SceneConfig(num_people=2, num_shots=2, num_frames=12, seed=3, image_size=(120, 200)), body)
    out = tmp_path_factory.mktemp("scene")
    paths = write_synthetic(out, video)
    return SimpleNamespace(video=video, dir=Path(out), video_path=paths["video"], truth_path=paths["ground_truth"],
                           truth=video.truth, world=video.truth.world)


def rigid_copy(world: WorldResult, body, rotation: np.ndarray, translation: np.ndarray) -> WorldResult:
    """The same people and cameras in another world frame ``x' = rotation x + translation`` (a reconstruction
    that chose a different world, as methods do). SMPL rotates about the pelvis, so ``transl`` is moved so that
    every vertex moves rigidly."""
    rest_pelvis = body.rest_joints(world.betas).detach().numpy().astype(np.float64)[:, 0]  # (P, 3)
    rot = Rotation.from_matrix(rotation)
    orient = (rot * Rotation.from_rotvec(world.global_orient.reshape(-1, 3))).as_rotvec()
    transl = (rest_pelvis[:, None] + world.transl) @ rotation.T + translation - rest_pelvis[:, None]
    R = world.R @ rotation.T
    t = world.t - np.einsum("tij,j->ti", R, translation)
    return dataclasses.replace(world, global_orient=orient.reshape(world.global_orient.shape), transl=transl,
                               R=R, t=t)


def tilted_rotation() -> np.ndarray:
    """A rotation that turns z-up into a tilted, non-axis up direction."""
    return Rotation.from_euler("xyz", [35.0, -20.0, 70.0], degrees=True).as_matrix()
