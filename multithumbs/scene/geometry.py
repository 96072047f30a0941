"""Scene geometry of a whole video from its pixels: every shot's camera trajectory and every cut's shared space.

:func:`scene_geometry` chains :func:`~multithumbs.scene.tracking.track_camera` (per shot) and
:func:`~multithumbs.scene.two_view.shared_space_at_cut` (per cut, on the frames
:func:`~multithumbs.scene.shots.boundary_frames` picks) into what :func:`multithumbs.pipeline.run_video`
takes. When both shots of a cut have static cameras, ``neighbour_frames`` frames on each side are passed
along for the ``neighbour_frames`` fallback.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from multithumbs.errors import InputError
from multithumbs.scene.shots import boundary_frames
from multithumbs.scene.tracking import TrackingConfig, track_camera
from multithumbs.scene.two_view import shared_space_at_cut
from multithumbs.scene.two_view_pose import TwoViewConfig
from multithumbs.types import CameraTrajectory, SharedSpace, Shots


@dataclass(frozen=True)
class SceneGeometry:
    """Trajectories (one per shot), shared spaces (one per cut) and the seconds each stage took.

    Attributes:
        trajectories: per shot.
        spaces: per cut.
        boundary: per cut ``(before, after)`` frames the space was built from.
        seconds: ``{"trajectories": s, "spaces": s}``.
    """

    trajectories: tuple[CameraTrajectory, ...]
    spaces: tuple[SharedSpace, ...]
    boundary: tuple[tuple[int, int], ...]
    seconds: dict[str, float] = field(default_factory=dict)


def scene_geometry(frames: np.ndarray, shots: Shots, K: np.ndarray, person_masks: np.ndarray | None = None,
                   tracking: TrackingConfig = TrackingConfig(), two_view: TwoViewConfig = TwoViewConfig(),
                   neighbour_frames: int = 2) -> SceneGeometry:
    """Camera trajectories and shared spaces of a video from its frames.

    Args:
        frames: ``(T, H, W, 3)`` uint8 RGB.
        shots: the video's shots.
        K: ``(3, 3)`` intrinsics of every frame, or ``(T, 3, 3)``.
        person_masks: ``(T, H, W)`` bool union of people per frame, or ``(T, P, H, W)`` per person, or None.
    """
    frames = np.asarray(frames)
    if frames.ndim != 4 or len(frames) != shots.num_frames:
        raise InputError(f"frames: expected ({shots.num_frames}, H, W, 3) frames for the shots, got {frames.shape}")
    K = np.asarray(K, np.float64)
    K_all = np.broadcast_to(K, (shots.num_frames, 3, 3)) if K.shape == (3, 3) else K
    if K_all.shape != (shots.num_frames, 3, 3):
        raise InputError(f"K: expected (3, 3) or ({shots.num_frames}, 3, 3), got {K.shape}")
    union = None
    if person_masks is not None:
        person_masks = np.asarray(person_masks, bool)
        union = person_masks.any(axis=1) if person_masks.ndim == 4 else person_masks
    start = time.perf_counter()
    trajectories = tuple(track_camera(frames[a:b], K_all[a], None if union is None else union[a:b], k, a, tracking)
                         for k, (a, b) in enumerate(shots.ranges))
    tracked = time.perf_counter()
    spaces, pairs = [], []
    for c in range(shots.cut_frames.size):
        frame_ids = cut_frames_needed(shots, c, trajectories[c].source == "static" and
                                      trajectories[c + 1].source == "static", neighbour_frames)
        space = cut_shared_space(shots, c, {f: frames[f] for f in frame_ids}, K_all,
                                 None if person_masks is None else {f: person_masks[f] for f in frame_ids}, two_view)
        spaces.append(space)
        pair = boundary_frames(shots, c)
        pairs.append((pair.before, pair.after))
    done = time.perf_counter()
    return SceneGeometry(trajectories, tuple(spaces), tuple(pairs),
                         {"trajectories": tracked - start, "spaces": done - tracked})


def cut_frames_needed(shots: Shots, cut_index: int, both_static: bool, neighbour_frames: int = 2) -> list[int]:
    """Video frames the shared space at a cut is built from: the boundary pair (:func:`boundary_frames`),
    then, when both shots' cameras are static, up to ``neighbour_frames`` more on each side (the
    ``neighbour_frames`` fallback), nearest first; outlier frames (``shots.outlier_frames``) are skipped."""
    pair = boundary_frames(shots, cut_index)
    needed = [pair.before, pair.after]
    if both_static and neighbour_frames > 0:
        lo, hi = shots.ranges[cut_index][0], shots.ranges[cut_index + 1][1]
        odd = set(shots.outlier_frames.tolist())
        needed += [f for f in range(pair.before - 1, lo - 1, -1) if f not in odd][:neighbour_frames]
        needed += [f for f in range(pair.after + 1, hi) if f not in odd][:neighbour_frames]
    return needed


def cut_shared_space(shots: Shots, cut_index: int, frames: dict[int, np.ndarray], K_all: np.ndarray,
                     person_masks: dict[int, np.ndarray] | None = None,
                     two_view: TwoViewConfig = TwoViewConfig()) -> SharedSpace:
    """The shared space at one cut from the frames :func:`cut_frames_needed` names.

    Args:
        shots: the video's shots.
        cut_index: which cut.
        frames: video frame index -> ``(H, W, 3)`` uint8 RGB, for every frame :func:`cut_frames_needed` lists.
        K_all: ``(T, 3, 3)`` intrinsics of every frame.
        person_masks: frame index -> ``(H, W)`` or ``(P, H, W)`` bool people masks, or None.
    """
    pair = boundary_frames(shots, cut_index)
    a, b = pair.before, pair.after
    extra_a = [f for f in frames if f < a]
    extra_b = [f for f in frames if f > b]
    extra_a.sort(reverse=True)
    extra_b.sort()
    masks = (lambda f: None) if person_masks is None else (lambda f: person_masks[f])
    return shared_space_at_cut(frames[a], frames[b], np.stack([K_all[a], K_all[b]]), masks(a), masks(b),
                               int(shots.cut_frames[cut_index]), two_view, [frames[f] for f in extra_a],
                               [frames[f] for f in extra_b], [masks(f) for f in extra_a], [masks(f) for f in extra_b])
