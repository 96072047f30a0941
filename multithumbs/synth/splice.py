"""Multi-view to multi-shot: frames ``[0, t1)`` from camera A, ``[t1, t2)`` from camera B, ...

The paper builds its benchmark this way from multi-view captures; the synthetic world and the real
dataset loaders share these functions.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from multithumbs.errors import InputError


def even_cuts(num_frames: int, num_shots: int, jitter: float = 0.0,
              rng: np.random.Generator | None = None, min_shot_length: int = 2) -> np.ndarray:
    """``(S-1,)`` cut frames splitting ``num_frames`` into ``num_shots`` shots of about equal length.

    Args:
        jitter: each cut moves by up to this fraction of a shot's length (needs ``rng``).
        min_shot_length: every shot keeps at least this many frames.
    """
    if num_shots < 1:
        raise InputError(f"shots: need at least one shot, got {num_shots}")
    if num_frames < num_shots * min_shot_length:
        raise InputError(f"frames: {num_frames} frames cannot hold {num_shots} shots of at least "
                         f"{min_shot_length} frames")
    length = num_frames / num_shots
    cuts = np.round(length * np.arange(1, num_shots)).astype(np.int64)
    if jitter and rng is not None and num_shots > 1:
        cuts = cuts + np.round(rng.uniform(-jitter, jitter, num_shots - 1) * length).astype(np.int64)
    edges = np.concatenate([[0], cuts, [num_frames]])
    for k in range(1, num_shots):  # keep every shot at least min_shot_length long
        edges[k] = np.clip(edges[k], edges[k - 1] + min_shot_length,
                           num_frames - (num_shots - k) * min_shot_length)
    return edges[1:-1]


def shot_camera_ids(num_frames: int, cut_frames: Sequence[int], camera_order: Sequence[int]) -> np.ndarray:
    """``(T,)`` the source camera of every frame: shot ``k`` comes from ``camera_order[k]``."""
    cuts = np.asarray(cut_frames, dtype=np.int64)
    if len(camera_order) != cuts.size + 1:
        raise InputError(f"camera_order: {len(camera_order)} cameras for {cuts.size + 1} shots")
    if cuts.size and (np.any(np.diff(cuts) <= 0) or cuts[0] <= 0 or cuts[-1] >= num_frames):
        raise InputError(f"cut_frames: must increase strictly inside (0, {num_frames}), got {cuts.tolist()}")
    shot = np.searchsorted(cuts, np.arange(num_frames), side="right")
    return np.asarray(camera_order, dtype=np.int64)[shot]


def splice_views(per_view: np.ndarray, camera_ids: np.ndarray) -> np.ndarray:
    """Pick each frame from its camera: ``per_view (V, T, ...)`` to ``(T, ...)``."""
    per_view = np.asarray(per_view)
    frames = np.arange(per_view.shape[1])
    return per_view[np.asarray(camera_ids), frames]
