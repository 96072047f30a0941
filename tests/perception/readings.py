"""BlazePose-shaped readings of a known body, for tests of what the CPU backend makes of them."""

from __future__ import annotations

import numpy as np
import torch

from multithumbs.perception.joints import BLAZEPOSE33_TO_SMPL24
from multithumbs.perception.pose_tracking import ShotPoses


def body_reading(body, orient: np.ndarray, transl: np.ndarray, K: np.ndarray,
                 seen: np.ndarray | None = None) -> ShotPoses:
    """One person's :class:`ShotPoses` of a zero-pose body turned by ``orient (3,)`` at ``transl (T, 3)``:
    its 12 joints that BlazePose's landmarks map onto projected through ``K`` (visibility 1), world
    landmarks about the mid-hip; nothing, and not valid, where ``seen (T,)`` is false (default: all seen)."""
    t = len(transl)
    seen = np.ones(t, bool) if seen is None else np.asarray(seen, bool)
    with torch.no_grad():
        joints = body.joints(np.tile(orient, (t, 1)), np.zeros((t, 23, 3)), np.zeros((t, 10)), transl).double().numpy()
    image, world = np.zeros((1, t, 33, 5)), np.zeros((1, t, 33, 3))
    uv = joints @ K.T
    for landmark, joint in BLAZEPOSE33_TO_SMPL24.items():
        image[0, :, landmark, :2] = uv[:, joint, :2] / uv[:, joint, 2:]
        image[0, :, landmark, 3:] = 1.0
        world[0, :, landmark] = joints[:, joint] - 0.5 * (joints[:, 1] + joints[:, 2])
    image[0, ~seen], world[0, ~seen] = 0.0, 0.0
    boxes = np.concatenate([image[..., :2].min(-2), image[..., :2].max(-2)], -1)
    return ShotPoses(np.array([0]), image, world, boxes, np.zeros((1, t, 360, 80), np.uint8), seen[None].copy())
