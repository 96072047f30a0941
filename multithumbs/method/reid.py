"""Cross-shot re-identification (paper §3.4): U = λgeo·D + λapp·A + λpos·P, Hungarian, reject D > τ.

D is the distance between root positions in the shared world frame (where the cameras of a cut mean
nothing, a shared space that fell back with nobody seen on both sides, D neither costs nor gates:
:attr:`Candidates.distance_known`), A the appearance dissimilarity
over regions valid in both (:mod:`multithumbs.appearance`), P the pose dissimilarity: the mean geodesic
angle between SMPL joint rotations, over joints whose 2D keypoints are confident in both frames.

Where a candidate was seen some time Δt from the cut (absent at it), the gate widens to τ + v·Δt, and a
person seen before is first carried along their walk to the other side's observation (constant velocity,
as a tracker predicts a lost track): D is measured there (:func:`fused_cost`). At the cut, both are the
paper's.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from multithumbs.appearance import appearance_dissimilarity
from multithumbs.method.config import ReidConfig  # noqa: F401  (defined there without torch; re-exported)
from multithumbs.geometry import axis_angle_to_matrix, rotation_angle


@dataclass(frozen=True)
class Candidates:
    """People on one side of a cut, as re-identification sees them.

    Attributes:
        root: ``(N, 3)`` world root positions near the cut.
        appearance: ``(N, D)`` appearance descriptors (see :mod:`multithumbs.appearance`).
        body_pose: ``(N, 23, 3)`` axis-angle body pose near the cut.
        joint_visible: ``(N, 23)`` bool, the body joint (SMPL joints 1..23) was visible.
        gap: ``(N,)`` seconds between the observation and the cut (0 at the boundary frame).
        distance_known: ``(N,)`` bool, the root's distance to the other side means something (every cut
            between its observation and the other side's has cameras from the scene or the people); where
            False, D neither costs nor gates and appearance and pose alone decide. None: all known.
        velocity: ``(N, 3)`` m/s world velocity of the root at the observation. On the side before, the
            root is carried by it to the other side's observation before D is measured. None: standing.
    """

    root: np.ndarray
    appearance: np.ndarray
    body_pose: np.ndarray
    joint_visible: np.ndarray
    gap: np.ndarray | None = None
    distance_known: np.ndarray | None = None
    velocity: np.ndarray | None = None


@dataclass(frozen=True)
class Matching:
    """The outcome of re-identification at one cut.

    Attributes:
        pairs: ``(M, 2)`` int, matched (before index, after index).
        cost: ``(N_before, N_after)`` the fused cost U.
        distance: ``(N_before, N_after)`` D in metres.
        appearance: ``(N_before, N_after)`` A.
        pose: ``(N_before, N_after)`` P in radians.
    """

    pairs: np.ndarray
    cost: np.ndarray
    distance: np.ndarray
    appearance: np.ndarray
    pose: np.ndarray


def pose_dissimilarity(pose_a: np.ndarray, pose_b: np.ndarray, visible_a: np.ndarray, visible_b: np.ndarray
                       ) -> np.ndarray:
    """``(Na, Nb)`` mean geodesic angle between body joint rotations over joints visible in both.

    Args:
        pose_a: ``(Na, 23, 3)``; pose_b: ``(Nb, 23, 3)`` axis-angle.
        visible_a: ``(Na, 23)``; visible_b: ``(Nb, 23)`` bool.
    Returns:
        radians; pairs with no joint visible in both get the mean over all joints.
    """
    Ra = axis_angle_to_matrix(pose_a)[:, None]
    Rb = axis_angle_to_matrix(pose_b)[None]
    angle = rotation_angle(np.broadcast_to(Ra, np.broadcast_shapes(Ra.shape, Rb.shape)),
                           np.broadcast_to(Rb, np.broadcast_shapes(Ra.shape, Rb.shape)))
    both = visible_a[:, None] & visible_b[None]
    count = both.sum(-1)
    return np.where(count > 0, (angle * both).sum(-1) / np.maximum(count, 1), angle.mean(-1))


def elapsed_seconds(before: Candidates, after: Candidates) -> np.ndarray:
    """``(Na, Nb)`` seconds between each pair's two observations: the sum of their gaps to the cut."""
    gap_a = before.gap if before.gap is not None else np.zeros(before.root.shape[0])
    gap_b = after.gap if after.gap is not None else np.zeros(after.root.shape[0])
    return np.asarray(gap_a, np.float64)[:, None] + np.asarray(gap_b, np.float64)[None]


def distance_gate(elapsed: np.ndarray, config: ReidConfig = ReidConfig()) -> np.ndarray:
    """τ widened by walking speed over the time between two observations: the farthest one person's
    roots may lie apart (m), same shape as ``elapsed`` (seconds)."""
    return config.max_distance + config.max_speed * np.asarray(elapsed, np.float64)


def fused_cost(before: Candidates, after: Candidates, config: ReidConfig = ReidConfig(),
               elapsed: np.ndarray | None = None
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """U and its parts for every pair: ``(cost, distance, appearance, pose, known)``, each ``(Na, Nb)``;
    ``known`` is where D means something (:attr:`Candidates.distance_known`) and so costs and gates.

    ``elapsed`` ``(Na, Nb)``: seconds between the two observations (default :func:`elapsed_seconds`).
    D is measured from the root before, carried by its :attr:`~Candidates.velocity` over them, for at most
    ``config.motion_window`` seconds: no further than the span the velocity was fit on."""
    elapsed = elapsed_seconds(before, after) if elapsed is None else np.asarray(elapsed, np.float64)
    carried = np.clip(elapsed, 0.0, max(config.motion_window, 0.0))
    root_before = before.root[:, None] + (0.0 if before.velocity is None else
                                          before.velocity[:, None] * carried[..., None])
    distance = np.linalg.norm(root_before - after.root[None], axis=-1)
    appearance = appearance_dissimilarity(before.appearance[:, None], after.appearance[None])
    pose = pose_dissimilarity(before.body_pose, after.body_pose, before.joint_visible, after.joint_visible)
    known = np.ones(distance.shape, bool)
    for side, axis in ((before, (slice(None), None)), (after, (None, slice(None)))):
        if side.distance_known is not None:
            known &= np.asarray(side.distance_known, bool)[axis]
    cost = config.w_geo * np.where(known, distance, 0.0) + config.w_app * appearance + config.w_pose * pose
    return cost, distance, appearance, pose, known


def match_people(before: Candidates, after: Candidates, config: ReidConfig = ReidConfig()) -> Matching:
    """Hungarian matching of people before and after a cut on U; pairs with D > τ are dropped."""
    n_a, n_b = before.root.shape[0], after.root.shape[0]
    if n_a == 0 or n_b == 0:
        empty = np.zeros((n_a, n_b))
        return Matching(np.zeros((0, 2), np.int64), empty, empty, empty, empty)
    elapsed = elapsed_seconds(before, after)
    cost, distance, appearance, pose, known = fused_cost(before, after, config, elapsed)
    rows, cols = linear_sum_assignment(cost)
    gate = distance_gate(elapsed, config)
    keep = (distance[rows, cols] <= gate[rows, cols]) | ~known[rows, cols]
    pairs = np.stack([rows[keep], cols[keep]], axis=1).astype(np.int64)
    return Matching(pairs, cost, distance, appearance, pose)
