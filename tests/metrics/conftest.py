"""Fixtures for the metric tests: a tiny stand-in body model and a two-shot synthetic scene."""

from __future__ import annotations

from types import SimpleNamespace
from typing import Callable

import numpy as np
import pytest
import roma
import torch

from multithumbs.geometry import (
    Similarity, axis_angle_to_matrix, intrinsics_from_fov, look_at, matrix_to_axis_angle, project_points,
    world_to_camera,
)
from multithumbs.metrics.identity import projected_boxes
from multithumbs.types import GroundTruth, WorldResult

# A rough SMPL-order skeleton in SMPL's body frame (+y up, faces +z, left is +x), joint 0 at the origin.
SKELETON = np.array([
    [0, 0, 0], [0.1, -0.1, 0], [-0.1, -0.1, 0], [0, 0.1, 0], [0.1, -0.5, 0], [-0.1, -0.5, 0],
    [0, 0.25, 0], [0.1, -0.9, 0], [-0.1, -0.9, 0], [0, 0.35, 0], [0.1, -0.95, 0.1], [-0.1, -0.95, 0.1],
    [0, 0.55, 0], [0.08, 0.5, 0], [-0.08, 0.5, 0], [0, 0.7, 0], [0.18, 0.5, 0], [-0.18, 0.5, 0],
    [0.45, 0.5, 0], [-0.45, 0.5, 0], [0.7, 0.5, 0], [-0.7, 0.5, 0], [0.78, 0.5, 0], [-0.78, 0.5, 0],
], dtype=np.float64)
VERTEX_OFFSETS = 0.03 * np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], dtype=np.float64)
PELVIS_HEIGHT = 0.95
"""Height of joint 0 above the floor when the fake body stands (its sole points are at 0.95 below)."""


class FakeBodyModel:
    """Joints = a fixed skeleton scaled by ``betas[0]``, moved by ``0.05 * body_pose``, rotated by
    ``global_orient`` about joint 0 and translated by ``transl``; four vertices around every joint."""

    num_vertices = len(SKELETON) * len(VERTEX_OFFSETS)
    foot_vertex_ids = None
    dtype = torch.float64

    def forward(self, global_orient, body_pose, betas, transl):
        skeleton = torch.as_tensor(SKELETON, dtype=transl.dtype)
        offsets = torch.as_tensor(VERTEX_OFFSETS, dtype=transl.dtype)
        local = skeleton * (1.0 + 0.1 * betas[..., :1, None])
        local = local + 0.05 * torch.cat([torch.zeros_like(body_pose[..., :1, :]), body_pose], dim=-2)
        rot = roma.rotvec_to_rotmat(global_orient)
        verts_local = (local[..., :, None, :] + offsets).reshape(*local.shape[:-2], -1, 3)
        place = lambda x: x @ rot.transpose(-1, -2) + transl[..., None, :]
        return SimpleNamespace(joints=place(local), vertices=place(verts_local))


@pytest.fixture
def body_model() -> FakeBodyModel:
    return FakeBodyModel()


def random_similarity(rng: np.random.Generator, batch: tuple[int, ...] = (), with_scale: bool = True) -> Similarity:
    """A random Sim(3) (SE(3) without scale) with the given batch shape."""
    generator = torch.Generator().manual_seed(int(rng.integers(2 ** 31)))
    rot = roma.random_rotmat(batch, dtype=torch.float64, generator=generator).numpy()
    scale = rng.uniform(0.5, 2.0, batch) if with_scale else np.ones(batch)
    return Similarity.from_numpy(scale, rot, rng.normal(0.0, 3.0, (*batch, 3)))


def _upright(heading: np.ndarray) -> np.ndarray:
    """``(..., 3)`` axis-angle of a standing body (SMPL +y to world +z) facing ``heading`` radians about z."""
    stand = axis_angle_to_matrix(np.array([np.pi / 2, 0.0, 0.0]))
    yaw = axis_angle_to_matrix(np.stack([np.zeros_like(heading), np.zeros_like(heading), heading], axis=-1))
    return matrix_to_axis_angle(yaw @ stand)


def build_scene(body: FakeBodyModel, num_people: int = 2, num_frames: int = 40, cut: int = 20,
                moving: bool = True, walking: bool = True, seed: int = 0) -> GroundTruth:
    """Two shots of people on the floor (z-up), walking or standing in place, seen by camera A then B."""
    rng = np.random.default_rng(seed)
    torch.manual_seed(seed)
    fps, width, height = 30.0, 640, 480
    frames = np.arange(num_frames)
    start = np.stack([rng.uniform(-1.5, 1.5, num_people), rng.uniform(-1.0, 1.0, num_people),
                      np.full(num_people, PELVIS_HEIGHT)], axis=-1)
    velocity = np.concatenate([rng.uniform(-1.0, 1.0, (num_people, 2)), np.zeros((num_people, 1))], axis=-1)
    velocity = velocity if walking else np.zeros_like(velocity)
    transl = start[:, None] + velocity[:, None] * (frames[None, :, None] / fps)
    heading = np.arctan2(velocity[:, 1], velocity[:, 0])[:, None] + 0.2 * np.sin(frames / 10.0)[None]
    global_orient = _upright(heading)
    swing = np.sin(frames / 5.0)[None, :, None, None]
    body_pose = 0.3 * rng.normal(size=(num_people, 1, 23, 3)) + 0.2 * swing * rng.normal(size=(num_people, 1, 23, 3))
    betas = np.zeros((num_people, 10))
    betas[:, 0] = rng.uniform(-1.0, 1.0, num_people)

    shot_b = frames >= cut
    eyes = np.where(shot_b[:, None], np.array([5.0, -4.0, 1.8]), np.array([0.0, -7.0, 1.6]))
    if moving:
        eyes = eyes + np.stack([0.03 * frames, 0.01 * np.sin(frames / 3.0), 0.02 * np.cos(frames / 4.0)], axis=-1)
    R, t = look_at(eyes, np.broadcast_to([0.0, 0.0, 1.0], eyes.shape))
    K = np.broadcast_to(intrinsics_from_fov(width, height, 60.0), (num_frames, 3, 3)).copy()

    betas_per_frame = np.repeat(betas[:, None], num_frames, axis=1)
    out = body.forward(*(torch.as_tensor(a) for a in (global_orient, body_pose, betas_per_frame, transl)))
    joints, vertices = out.joints.numpy(), out.vertices.numpy()
    uv = project_points(joints, K, R, t)
    keypoints = np.concatenate([uv, np.ones((*uv.shape[:-1], 1))], axis=-1)
    boxes, in_image = projected_boxes(world_to_camera(vertices, R, t), K, (height, width))
    assert in_image.all(), "the test scene keeps everyone in view"
    cut_frames = np.array([cut])
    world = WorldResult(
        person_ids=np.arange(num_people), global_orient=global_orient, body_pose=body_pose,
        betas=betas, transl=transl, valid=np.ones((num_people, num_frames), bool), K=K, R=R, t=t,
        cut_frames=cut_frames, fps=fps, image_size=(height, width),
        id_map=np.array([[s, q, q] for s in range(2) for q in range(num_people)]), keypoints2d=keypoints)
    return GroundTruth(world, boxes, np.ones((num_people, num_frames), bool), shot_b.astype(np.int64))


@pytest.fixture
def scene(body_model) -> Callable[..., GroundTruth]:
    """``scene(**kwargs)`` builds :func:`build_scene` with the fake body model."""
    return lambda **kwargs: build_scene(body_model, **kwargs)
