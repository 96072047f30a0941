"""BVH motion of one person on the SMPL skeleton.

Hierarchy: SMPL's 24 joints with their names (:data:`multithumbs.conventions.SMPL_JOINT_NAMES`) and kinematic
tree; each joint's ``OFFSET`` is its rest offset from its parent in the person's shaped T-pose
(``body.rest_joints(betas)``, SMPL's body frame: +y up, facing +z); the root (pelvis) has offset zero and
six channels, the others three. Leaf joints (feet, head, hands) end in an ``End Site`` half their own
offset further along. Units are metres (``scale`` changes that, e.g. 100 for centimetres).

Motion: one row per video frame (``Frame Time`` = 1 / fps). The root's position channels are the pelvis'
world position, its rotation the SMPL ``global_orient``; the others are the SMPL ``body_pose`` rotations.
The world is turned so that its estimated up direction is BVH's +y (:func:`multithumbs.export.posed.
rotation_to_y_up`; a z-up world becomes ``(x, z, -y)``). Rotations are Euler angles in degrees in the
channel order ``Zrotation Xrotation Yrotation``, i.e. ``R = Rz Rx Ry`` (intrinsic ZXY), the common BVH
reading. Frames where the person is not valid repeat the nearest valid frame, so the file stays aligned
with the video; the SMPL ``.npz`` export has the validity.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import torch
from scipy.spatial.transform import Rotation

from multithumbs.conventions import SMPL_JOINT_NAMES, SMPL_PARENTS
from multithumbs.errors import InputError
from multithumbs.export.files import write_text_atomic
from multithumbs.types import WorldResult

EULER_ORDER = "ZXY"
"""scipy's intrinsic Euler order matching the channels ``Zrotation Xrotation Yrotation``."""


def nearest_valid_frames(valid: np.ndarray) -> np.ndarray:
    """``(T,)`` int: for every frame, itself when valid, else the nearest valid frame (earlier on ties)."""
    valid = np.asarray(valid, bool)
    idx = np.nonzero(valid)[0]
    if idx.size == 0:
        raise InputError("valid: the person is never valid")
    frames = np.arange(valid.size)
    pos = np.clip(np.searchsorted(idx, frames), 1, max(idx.size - 1, 1))
    if idx.size == 1:
        return np.full(valid.size, idx[0])
    before, after = idx[pos - 1], idx[pos]
    return np.where(frames - before <= after - frames, before, after)


def bvh_text(result: WorldResult, person: int, rest_joints: np.ndarray, pelvis: np.ndarray,
             to_y_up: np.ndarray, scale: float = 1.0, decimals: int = 6) -> str:
    """The BVH file of one person (module docstring).

    Args:
        result: the reconstruction.
        person: row of ``result``.
        rest_joints: ``(24, 3)`` the person's rest-pose joints (``body.rest_joints(betas)``).
        pelvis: ``(T, 3)`` the person's posed world pelvis (joint 0) per frame.
        to_y_up: ``(3, 3)`` rotation from the world to BVH's y-up frame.
        scale: length unit factor (1 = metres).
        decimals: digits after the point of every number.
    """
    rest = np.asarray(rest_joints, np.float64)
    if rest.shape != (24, 3):
        raise InputError(f"rest_joints: expected shape (24, 3), got {rest.shape}")
    frames = nearest_valid_frames(result.valid[person])
    children: dict[int, list[int]] = {j: [] for j in range(24)}
    for j, parent in enumerate(SMPL_PARENTS):
        if parent >= 0:
            children[parent].append(j)
    fmt = f"{{:.{decimals}f}}"
    vec = lambda v: " ".join(fmt.format(x) for x in v)  # noqa: E731

    lines = ["HIERARCHY"]

    def joint(j: int, depth: int) -> None:
        pad = "\t" * depth
        offset = np.zeros(3) if j == 0 else (rest[j] - rest[SMPL_PARENTS[j]]) * scale
        lines.append(f"{pad}{'ROOT' if j == 0 else 'JOINT'} {SMPL_JOINT_NAMES[j]}")
        lines.append(pad + "{")
        lines.append(f"{pad}\tOFFSET {vec(offset)}")
        lines.append(f"{pad}\tCHANNELS " + ("6 Xposition Yposition Zposition " if j == 0 else "3 ")
                     + "Zrotation Xrotation Yrotation")
        for c in children[j]:
            joint(c, depth + 1)
        if not children[j]:
            lines.append(f"{pad}\tEnd Site")
            lines.append(pad + "\t{")
            lines.append(f"{pad}\t\tOFFSET {vec(0.5 * offset)}")
            lines.append(pad + "\t}")
        lines.append(pad + "}")

    joint(0, 0)
    root_rot = Rotation.from_matrix(to_y_up) * Rotation.from_rotvec(result.global_orient[person, frames])
    local = Rotation.from_rotvec(np.asarray(result.body_pose[person, frames], np.float64).reshape(-1, 3))
    eulers = np.concatenate([root_rot.as_euler(EULER_ORDER, degrees=True)[:, None],
                             local.as_euler(EULER_ORDER, degrees=True).reshape(len(frames), 23, 3)], axis=1)
    position = (np.asarray(pelvis, np.float64)[frames] @ np.asarray(to_y_up).T) * scale
    # Joint order of the motion rows is the depth-first order of the hierarchy.
    order = [int(line.split()[1] in SMPL_JOINT_NAMES and SMPL_JOINT_NAMES.index(line.split()[1]))
             for line in lines if line.strip().startswith(("ROOT", "JOINT"))]
    motion = np.concatenate([position, eulers[:, order].reshape(len(frames), -1)], axis=1)
    lines += ["MOTION", f"Frames: {len(frames)}", f"Frame Time: {1.0 / result.fps:.9f}"]
    lines += [" ".join(fmt.format(x) for x in row) for row in motion]
    return "\n".join(lines) + "\n"


def write_bvh(path: str | Path, result: WorldResult, person: int, body, joints: np.ndarray,
              to_y_up: np.ndarray, scale: float = 1.0) -> Path:
    """Write one person's BVH (module docstring) atomically.

    Args:
        path: output ``.bvh``.
        result: the reconstruction.
        person: row of ``result``.
        body: the body model (for the shaped rest joints).
        joints: ``(T, 24, 3)`` the person's posed world joints.
        to_y_up: ``(3, 3)`` world to BVH frame rotation.
        scale: length unit factor (1 = metres).
    """
    with torch.no_grad():
        rest = body.rest_joints(result.betas[person]).detach().cpu().double().numpy()
    return write_text_atomic(path, bvh_text(result, person, rest, np.asarray(joints)[:, 0], to_y_up, scale))
