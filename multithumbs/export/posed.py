"""Posed meshes and joints of a :class:`WorldResult`, and the world's up direction, for exports and pictures.

A reconstructed world is whatever frame the method chose (:mod:`multithumbs.conventions`), so formats with
a fixed up axis (glTF and BVH: +y; rerun: told explicitly; top-down plots) get the up direction estimated
from the people (they mostly stand) and rotate the world to it at the edge.
"""

from __future__ import annotations

import numpy as np
import torch

from multithumbs.conventions import NUM_BETAS, NUM_JOINTS
from multithumbs.errors import InputError
from multithumbs.metrics.gt_free import estimate_up
from multithumbs.types import WorldResult

AXIS_SNAP_DEG = 10.0
"""An estimated up direction within this angle of a world axis is snapped to that axis (a z-up ground
truth world then plots and exports exactly z-up)."""


def posed_people(result: WorldResult, body, people: np.ndarray | None = None,
                 frames: np.ndarray | None = None, chunk: int = 512) -> tuple[np.ndarray, np.ndarray]:
    """Pose people of ``result`` with the body model, in the world frame.

    Args:
        result: the reconstruction.
        body: a :class:`multithumbs.body.model.BodyModel` (anything with the same ``forward``).
        people: ``(P',)`` person indices (rows of ``result``), all when None.
        frames: ``(T',)`` frame indices, all when None.
        chunk: poses per body-model call (bounds memory).
    Returns:
        ``vertices (P', T', V, 3)`` float32 and ``joints (P', T', 24, 3)`` float64, world frame, metres.
        Frames where a person is not valid are posed from whatever parameters the result holds there;
        use ``result.valid`` to tell.
    """
    p_idx = np.arange(result.num_people) if people is None else np.asarray(people, dtype=np.int64).reshape(-1)
    f_idx = np.arange(result.num_frames) if frames is None else np.asarray(frames, dtype=np.int64).reshape(-1)
    num_v = int(body.num_vertices)
    vertices = np.zeros((len(p_idx), len(f_idx), num_v, 3), np.float32)
    joints = np.zeros((len(p_idx), len(f_idx), NUM_JOINTS, 3))
    for i, p in enumerate(p_idx):
        for start in range(0, len(f_idx), chunk):
            sel = f_idx[start:start + chunk]
            with torch.no_grad():
                out = body.forward(result.global_orient[p, sel], result.body_pose[p, sel],
                                   np.broadcast_to(result.betas[p], (len(sel), NUM_BETAS)), result.transl[p, sel])
            vertices[i, start:start + len(sel)] = out.vertices.detach().cpu().numpy()
            joints[i, start:start + len(sel)] = out.joints.detach().cpu().double().numpy()
    return vertices, joints


def posed_joints(result: WorldResult, body) -> np.ndarray:
    """``(P, T, 24, 3)`` world joints of everyone in every frame (no mesh skinning: fast)."""
    p, t = result.valid.shape
    if p == 0:
        return np.zeros((0, t, NUM_JOINTS, 3))
    with torch.no_grad():
        joints = body.joints(result.global_orient, result.body_pose, result.betas, result.transl)
    return joints.detach().cpu().double().numpy()


def world_up(result: WorldResult, joints: np.ndarray | None = None) -> np.ndarray:
    """The world's ``(3,)`` unit up direction.

    From the people's pelvis-to-neck direction (:func:`multithumbs.metrics.gt_free.estimate_up`) when any
    person is valid, else from the cameras (orthogonal to every camera's right axis: footage is shot
    without roll; see ``_camera_up``). Snapped to a world axis within :data:`AXIS_SNAP_DEG`.

    Args:
        result: the reconstruction.
        joints: ``(P, T, 24, 3)`` its world joints, when already computed (else the cameras are used
            unless the caller passes them).
    """
    up = None
    if joints is not None and result.valid.any():
        up = estimate_up(joints, result.valid)
    if up is None:
        up = _camera_up(np.asarray(result.R, np.float64))
    axis = int(np.argmax(np.abs(up)))
    if np.abs(up[axis]) >= np.cos(np.deg2rad(AXIS_SNAP_DEG)):
        up = np.sign(up[axis]) * np.eye(3)[axis]
    return up


def _camera_up(R: np.ndarray) -> np.ndarray:
    """Up from cameras ``R (T, 3, 3)`` shot without roll: orthogonal to every camera's right axis (exact when
    the cameras look in at least two directions), signed like the image's up axis; else the mean image up."""
    image_up = -R[:, 1, :].mean(axis=0)
    _, singular, vt = np.linalg.svd(R[:, 0, :])
    if singular.size == 3 and singular[1] > 1e-3 * max(singular[0], 1e-12):
        up = vt[2] * np.sign(vt[2] @ image_up or 1.0)
    else:
        up = image_up
    norm = np.linalg.norm(up)
    if not norm > 1e-9:
        raise InputError("result.R: cannot tell the world's up direction (no valid person, cameras disagree)")
    return up / norm


def rotation_to_y_up(up: np.ndarray) -> np.ndarray:
    """``(3, 3)`` rotation taking the world's ``up (3,)`` to ``+y`` (the up axis of glTF and BVH).

    For a z-up world this is the usual -90 degree turn about x: ``(x, y, z) -> (x, z, -y)``.
    """
    up = np.asarray(up, float) / np.linalg.norm(up)
    y = np.array([0.0, 1.0, 0.0])
    axis = np.cross(up, y)
    s, c = np.linalg.norm(axis), float(up @ y)
    if s < 1e-12:
        return np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
    k = axis / s
    skew = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + s * skew + (1 - c) * skew @ skew


def rotation_to_z_up(up: np.ndarray) -> np.ndarray:
    """``(3, 3)`` rotation taking the world's ``up (3,)`` to ``+z`` (for top-down plots and rerun)."""
    to_y = rotation_to_y_up(up)
    y_to_z = np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]])  # (x, y, z) -> (x, -z, y): +y to +z
    return y_to_z @ to_y


def shot_index(result: WorldResult) -> np.ndarray:
    """``(T,)`` int shot of every frame."""
    return np.searchsorted(result.cut_frames, np.arange(result.num_frames), side="right")


def camera_centres(result: WorldResult) -> np.ndarray:
    """``(T, 3)`` world camera centres ``C = -R^T t``."""
    return -np.einsum("tji,tj->ti", result.R, result.t)
