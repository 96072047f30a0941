"""Short gaps in a followed person's track bridged by the body between the readings on either side.

A person walking behind someone, or read badly for a few frames, leaves a gap in their track although
the tracker picks them up again as the same person. A tracker of the field does not let the mesh blink
out there: PHALP keeps predicting a lost track for up to 50 frames (``max_age_track``), and MOT trackers'
post-processing (ByteTrack's ``interpolation.py``, ``n_dti=20``; mmtracking's ``InterpolateTracklets``)
fills gaps of up to 20 frames with boxes interpolated linearly. Here a gap of at most
``max_gap`` frames between two readings of one track is filled with the body between them: the SMPL
translation linearly, the root and joint rotations by slerp, the shape unchanged (one per track).

What was observed stays told apart from what was bridged: a bridged frame is ``valid`` (the person has
a body there) but its keypoints carry confidence 0 (the fitted body's joints projected through ``K``, so
that later stages weigh no evidence there), its mask is empty and its appearance is not valid.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import roma
import torch

from multithumbs.conventions import NUM_JOINTS
from multithumbs.types import PersonTracks


@dataclass(frozen=True)
class GapFillConfig:
    """Which gaps in a track are bridged."""

    max_gap: int = 20
    """Longest run of frames without a reading, between two readings of the same track, that is bridged
    (frames; 0 bridges nothing). ByteTrack's and mmtracking's interpolation bridge up to 20."""


def bridgeable(valid: np.ndarray, max_gap: int) -> np.ndarray:
    """``(P, T)`` bool: the frames of ``valid (P, T)`` that lie in a run of at most ``max_gap`` invalid
    frames with a valid frame on both sides (a track's ends are never extended)."""
    valid = np.asarray(valid, bool)
    out = np.zeros_like(valid)
    for p, row in enumerate(valid):
        seen = np.flatnonzero(row)
        for a, b in zip(seen[:-1], seen[1:]):
            if 1 < b - a <= max_gap + 1:
                out[p, a + 1:b] = True
    return out


def bridge_gaps(tracks: PersonTracks, body, config: GapFillConfig = GapFillConfig()) -> PersonTracks:
    """``tracks`` with every :func:`bridgeable` gap filled (module docstring); unchanged when there is none.

    Args:
        tracks: one shot's people; ``keypoints2d`` in SMPL order (``J = 24``) gets the bridged frames'
            projected joints, any other ``J`` stays zero there.
        body: the body model the tracks were fitted with (for the bridged joints).
    """
    fill = bridgeable(tracks.valid, config.max_gap)
    if not fill.any():
        return tracks
    orient, pose = tracks.global_orient.copy(), tracks.body_pose.copy()
    transl = tracks.transl.copy()
    for p, row in enumerate(tracks.valid):
        seen = np.flatnonzero(row)
        for a, b in zip(seen[:-1], seen[1:]):
            if not fill[p, a + 1:b].any():
                continue
            steps = torch.as_tensor((np.arange(a + 1, b) - a) / (b - a))
            ends = torch.as_tensor(np.stack([np.concatenate([orient[p, a][None], pose[p, a]]),
                                             np.concatenate([orient[p, b][None], pose[p, b]])]))
            between = roma.rotvec_slerp(ends[0], ends[1], steps).numpy()  # (b - a - 1, 24, 3)
            orient[p, a + 1:b], pose[p, a + 1:b] = between[:, 0], between[:, 1:]
            transl[p, a + 1:b] = transl[p, a] + steps.numpy()[:, None] * (transl[p, b] - transl[p, a])
    keypoints = tracks.keypoints2d.copy()
    if keypoints.shape[2] == NUM_JOINTS:
        people, frames = np.nonzero(fill)
        with torch.no_grad():
            joints = body.joints(torch.as_tensor(orient[people, frames]), torch.as_tensor(pose[people, frames]),
                                 torch.as_tensor(tracks.betas[people]), torch.as_tensor(transl[people, frames]))
        joints = joints.double().numpy()
        uvw = joints @ np.asarray(tracks.K, np.float64).T
        keypoints[people, frames, :, :2] = uvw[..., :2] / np.maximum(uvw[..., 2:], 1e-6)
        keypoints[people, frames, :, 2] = 0.0
    masks = tracks.masks.copy()
    masks[fill] = 0  # padding may hold anything (docs/CONVENTIONS.md); a bridged frame shows no pixels
    return replace(tracks, global_orient=orient, body_pose=pose, transl=transl, keypoints2d=keypoints, masks=masks,
                   valid=tracks.valid | fill)
