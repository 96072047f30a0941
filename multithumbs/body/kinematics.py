"""SMPL posing algebra for :class:`multithumbs.body.model.BodyModel`: Rodrigues' formula on coordinate-major
rotation vectors and the kinematic tree composed level by level (one batched product per tree depth).
"""

from __future__ import annotations

import itertools

import numpy as np
import torch

from multithumbs.errors import InputError


_SKEW_BASIS = torch.tensor([[0.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0],
                            [0.0, 0.0, 1.0], [0.0, 0.0, 0.0], [-1.0, 0.0, 0.0],
                            [0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
"""``(9, 3)``: ``_SKEW_BASIS @ k`` is ``[k]x = [[0, -z, y], [z, 0, -x], [-y, x, 0]]`` flattened row-major."""


def rodrigues_coordinate_major(rotvec: torch.Tensor) -> torch.Tensor:
    """Axis-angle ``(3, ...)`` to rotation matrices ``(3, 3, ...)``, coordinates leading.

    smplx's ``batch_rodrigues`` to rounding: the same formula ``I + sin θ K + (1 - cos θ) K²`` (here with
    ``K² = k kᵀ - |k|² I``) and the same ``1e-8`` offset in the angle, so a zero vector gives the identity
    with a finite gradient. With the coordinates leading, every op runs on contiguous rows of the batch,
    which is much faster on CPU than batched 3x3 products or reductions over a trailing dimension of 3.
    """
    angle = (rotvec + 1e-8).square().sum(0, keepdim=True).sqrt()
    axis = rotvec / angle
    skew = (_SKEW_BASIS.to(rotvec.dtype) @ axis.reshape(3, -1)).reshape(3, 3, *rotvec.shape[1:])
    outer = axis.unsqueeze(1) * axis.unsqueeze(0)
    eye = torch.eye(3, dtype=rotvec.dtype).reshape(3, 3, *(1,) * (rotvec.ndim - 1))
    # |k| is 1 up to the angle's offset, which smplx's K @ K keeps: so does |k|² here.
    return eye + torch.sin(angle) * skew + (1 - torch.cos(angle)) * (outer - eye * axis.square().sum(0, keepdim=True))


class _KinematicLevels:
    """A kinematic tree walked one depth level at a time (joints of one level are posed together).

    Works coordinate-major (joints on dimension -2, the batch last), see :meth:`pose`. With SMPL's
    breadth-first joint order each level is a contiguous block and most parent lookups are slices.
    """

    def __init__(self, parents: np.ndarray):
        parents = np.asarray(parents, np.int64)
        count = len(parents)
        depth = np.zeros(count, np.int64)
        for j in range(1, count):
            if not 0 <= parents[j] < j:
                raise InputError(f"SMPL model: kinematic tree joint {j} has parent {parents[j]}, "
                                 "expected an earlier joint")
            depth[j] = depth[parents[j]] + 1
        order = np.argsort(depth, kind="stable")
        self.reorder = None if np.array_equal(order, np.arange(count)) else torch.as_tensor(order)
        self.restore = None if self.reorder is None else torch.as_tensor(np.argsort(order))
        has_child = np.zeros(count, bool)
        has_child[parents[1:]] = True
        self.sizes = [int((depth == d).sum()) for d in range(depth.max() + 1)]
        levels = np.split(order, np.cumsum(self.sizes)[:-1])
        # Per level after the root: where each joint's parent sits among the previous level's joints
        # (positions) and among those of them with children (rotations), and which joints have children.
        self.steps = []
        for prev, ids in itertools.pairwise(levels):
            prev_rot = [j for j in prev if has_child[j]]
            self.steps.append((_lookup([list(prev).index(p) for p in parents[ids]]),
                               _lookup([prev_rot.index(p) for p in parents[ids]]),
                               _lookup([i for i, j in enumerate(ids) if has_child[j]])))

    def pose(self, rotations: torch.Tensor, rest: torch.Tensor) -> torch.Tensor:
        """``(3, J, N)`` posed joints from local rotations ``(3, 3, J, N)`` and rest joints ``(3, J, N)``.

        Each level: ``x_j = x_parent + G_parent (r_j - r_parent)`` and, for joints with children,
        ``G_j = G_parent R_j``. The root stays at its rest position (as in smplx's ``batch_rigid_transform``).
        """
        if self.reorder is not None:
            rest, rotations = rest.index_select(-2, self.reorder), rotations.index_select(-2, self.reorder)
        rest_levels = rest.split(self.sizes, dim=-2)
        rotation_levels = rotations.split(self.sizes, dim=-2)
        posed = [rest_levels[0]]
        frames = rotation_levels[0]                       # global rotations of the level's joints with children
        for (pos_of_parent, rot_of_parent, with_children), prev_rest, level_rest, local in zip(
                self.steps, rest_levels[:-1], rest_levels[1:], rotation_levels[1:]):
            parent_rot = rot_of_parent(frames)
            offset = level_rest - pos_of_parent(prev_rest)
            posed.append(pos_of_parent(posed[-1]) + (parent_rot * offset.unsqueeze(0)).sum(1))
            if with_children is not None:
                frames = (with_children(parent_rot).unsqueeze(2) * with_children(local).unsqueeze(0)).sum(1)
        out = torch.cat(posed, dim=-2)
        return out if self.restore is None else out.index_select(-2, self.restore)


def _lookup(index: list[int]):
    """``f(x)`` selecting ``x[..., index, :]`` (a slice or a broadcast where the index allows one);
    None for an empty index."""
    if len(index) == 0:
        return None
    first, count = index[0], len(index)
    if index == list(range(first, first + count)):
        return lambda x: x[..., first:first + count, :]
    if all(i == first for i in index):
        return lambda x: x[..., first:first + 1, :].expand(*x.shape[:-2], count, x.shape[-1])
    positions = torch.as_tensor(index)
    return lambda x: x.index_select(-2, positions)
