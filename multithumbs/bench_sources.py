"""Where the bench's inputs come from: simulated from the truth, through an upstream-shaped file, or
computed from the rendered pixels one stage at a time (:data:`INPUT_SOURCES`, :data:`PIXEL_STAGES`).

:mod:`multithumbs.bench` runs the method on them; this module makes them.
"""

from __future__ import annotations

import math
from typing import Protocol, Sequence

import numpy as np

from multithumbs.errors import InputError

BACKENDS = {"perception": "simulated", "shared_space": "simulated (stands in for VGGT)",
            "camera_tracking": "simulated (stands in for DROID-SLAM)", "shots": "ground truth cuts"}


PERCEPTION_ROUTES = ("direct", "phalp")
"""How the simulated perception reaches the method: as tracks (``direct``), or written the way 4DHumans/PHALP
writes its results and read back as ``multithumbs run --perception phalp:`` reads them (``phalp``: 1-based
frame names, ghosts, confirmation, HMR2-camera ``2d_joints`` reprojected, appearance from the pixels)."""


INPUT_SOURCES = ("simulated", "pixels", "pixels_no_focal")
"""Where the method's inputs come from: ``simulated`` (perception, shared spaces and camera tracking made
from the truth, cuts exact) or ``pixels`` (nothing simulated: cuts by scenedetect on the encoded video,
people by the CPU perception backend, camera trajectories and shared spaces by pycolmap, all from the
frames a user's decoder gives); ``pixels_no_focal`` as ``pixels`` with the true focal length withheld and
estimated from the pixels (:func:`multithumbs.scene.focal.estimate_focal`)."""
PIXEL_BACKENDS = {"shots": "scenedetect:adaptive on the encoded video", "perception": "blazepose with nanodet proposals (CPU)",
                  "camera_tracking": "pycolmap", "shared_space": "pycolmap"}


PIXEL_STAGES = ("shots", "perception", "camera_tracking", "shared_space")
"""The input stages ``bench --from-pixels`` computes from the frames; ``--pixel-stages`` takes a subset, the
others simulated as in the simulated suite (the stage-by-stage swap of ``docs/RESULTS.md``)."""


class InputCache(Protocol):
    """Where :func:`run_scene_results` keeps a scene's pixel inputs between runs (the CLI's is the artifact
    store, ``tasks.bench_inputs``); ``params`` say everything the inputs depend on besides the code."""

    def load(self, params: dict) -> tuple | None:
        """``(shots, tracks, trajectories, spaces, backends, seconds)`` kept under ``params``, or None."""

    def save(self, params: dict, value: tuple) -> None:
        """Keep ``value`` under ``params``."""


def checked_pixel_stages(names: str | Sequence[str] | None) -> tuple[str, ...]:
    """The stages named (comma-separated or a sequence; ``None``: all of :data:`PIXEL_STAGES`), checked."""
    if names is None:
        return PIXEL_STAGES
    listed = [n.strip() for n in (names.split(",") if isinstance(names, str) else names) if n.strip()]
    unknown = [n for n in listed if n not in PIXEL_STAGES]
    if unknown or not listed:
        raise InputError(f"pixel stages {','.join(unknown) or '(none)'}: expected some of {', '.join(PIXEL_STAGES)}")
    return tuple(n for n in PIXEL_STAGES if n in listed)


def pixel_input_params(scene: dict, stages: Sequence[str] = PIXEL_STAGES, withhold_focal: bool = False,
                       seed: int = 0) -> dict:
    """What a scene's pixel inputs depend on besides the code, the key of :class:`InputCache`: the scene's
    settings (``config_to_json``), the stages taken from the pixels, whether the focal length was withheld,
    the seed of the simulated stages and the kernels BlazePose's XNNPACK computed with (it has no switch to
    pin, :func:`multithumbs.cpu_kernels.network_kernel_tag`)."""
    from multithumbs.cpu_kernels import network_kernel_tag

    return {"scene": scene, "stages": list(checked_pixel_stages(stages)), "withhold_focal": withhold_focal,
            "seed": seed, "network_kernels": network_kernel_tag()}


def pixel_inputs(video, body, seconds: dict[str, float] | None = None, withhold_focal: bool = False,
                 stages: Sequence[str] = PIXEL_STAGES, seed: int = 0):
    """The method's inputs of a rendered scene with the ``stages`` (of :data:`PIXEL_STAGES`) computed from
    the pixels and the others simulated from the truth (all four: nothing simulated, :data:`INPUT_SOURCES`).

    The frames are encoded as MPEG-4 and decoded again, as a user's video would be. Intrinsics are the
    true ones, or with ``withhold_focal`` estimated as ``multithumbs run`` estimates them for a video
    without ``--intrinsics`` (``backends["focal"]`` says from what, and ``seconds["focal"]`` how long).
    Simulated perception keeps the true cuts, so a swap with ``shots`` from the pixels and perception
    simulated needs the detected cuts to be the true ones.
    Returns ``(shots, tracks, trajectories, spaces, backends)``: ``backends`` names what made
    each stage (the trajectories' and spaces' own sources, fallbacks included); ``seconds`` (when given)
    receives each stage's wall time.
    """
    import tempfile
    import time
    from pathlib import Path

    from multithumbs.perception.appearance import fill_appearance
    from multithumbs.perception.blazepose_backend import blazepose_tracks
    from multithumbs.scene.geometry import scene_geometry
    from multithumbs.scene.shots import detect_shots
    from multithumbs.synth.files import write_video
    from multithumbs.synth.perception import simulate_perception
    from multithumbs.synth.simulated_geometry import simulate_camera_trajectory, simulate_shared_space
    from multithumbs.video import read_frames

    stages = checked_pixel_stages(stages)
    seconds = {} if seconds is None else seconds
    K = video.truth.world.K[0]
    with tempfile.TemporaryDirectory(prefix="mt_pixels_") as tmp:
        path = write_video(Path(tmp) / "video.mp4", video.frames, video.truth.world.fps)
        start = time.perf_counter()
        shots = detect_shots(path) if "shots" in stages else video.truth.world.shots()
        seconds["shots"] = time.perf_counter() - start
        frames = read_frames(path)
    exact = np.array_equal(shots.cut_frames, video.truth.world.cut_frames)
    if not exact and "perception" not in stages:
        raise InputError(f"the detected cuts {shots.cut_frames.tolist()} are not the true "
                         f"{video.truth.world.cut_frames.tolist()}, and simulated perception needs the true ones")
    focal = None
    if withhold_focal:
        from multithumbs.scene.focal import estimate_focal, frames_estimate
        from multithumbs.scene.two_view import default_intrinsics

        start = time.perf_counter()
        motion = frames_estimate(frames, shots.ranges)
        h, w = frames.shape[1:3]
        K = default_intrinsics(w, h) if motion[0] is None else motion[0].K(w, h)
        seconds["focal"] = time.perf_counter() - start
    if "perception" in stages:
        tracks, split = blazepose_tracks(iter(frames), shots, K, body)
        seconds["perception_landmarks"], seconds["perception_fitting"] = split.landmarks, split.fitting
        seconds["perception_detection"] = split.detection
        start = time.perf_counter()
        tracks = fill_appearance(tracks, frames)
        seconds["appearance"] = time.perf_counter() - start
    else:
        tracks = simulate_perception(video, body, seed=seed)
    if withhold_focal:
        focal = estimate_focal(frames, shots.ranges, tracks=tracks, from_frames=motion)
        K = focal.K(w, h)  # the tracks keep the K they were fitted in: the method re-expresses them
    geometry = None
    if "camera_tracking" in stages or "shared_space" in stages:
        masks = np.concatenate([tr.people_mask() for tr in tracks])
        geometry = scene_geometry(frames, shots, K, masks)
        seconds["camera_tracking"] = geometry.seconds.get("trajectories", math.nan)
        seconds["shared_space"] = geometry.seconds.get("spaces", math.nan)
    # Each simulated stage draws from its own seeded generator: only the ones used are made.
    trajectories = (list(geometry.trajectories) if "camera_tracking" in stages else
                    [simulate_camera_trajectory(video, k, seed=seed) for k in range(shots.num_shots)])
    spaces = (list(geometry.spaces) if "shared_space" in stages else
              [simulate_shared_space(video, c, seed=seed) for c in range(len(shots.cut_frames))])
    backends = dict(BACKENDS)
    if "shots" in stages:
        backends["shots"] = f"{shots.source} ({'exact' if exact else 'cuts differ'})"
    if "perception" in stages:
        backends["perception"] = PIXEL_BACKENDS["perception"]
    if "camera_tracking" in stages:
        backends["camera_tracking"] = ", ".join(sorted({t.source for t in trajectories}))
    if "shared_space" in stages:
        backends["shared_space"] = ", ".join(sorted({s.source + (f" -> {s.fallback}" if s.fallback else "")
                                                     for s in spaces})) or "none (one shot)"
    if focal is not None:
        truth = float(video.truth.world.K[0, 0, 0])
        backends["focal"] = f"{focal.line()}; truth {truth:.0f} px, error {100 * (focal.focal_px / truth - 1):+.1f} %"
    return shots, tracks, trajectories, spaces, backends


def through_phalp_file(tracks: Sequence, video, body) -> list:
    """Simulated per-shot tracks through an upstream-shaped PHALP results file and back.

    Args:
        tracks: per-shot :class:`~multithumbs.types.PersonTracks` of the scene.
        video: the synthesised scene (its frames, for appearance; its truth, for shots and intrinsics).
        body: the body model (posing for the file's joints and for the reprojected keypoints).
    Returns:
        the tracks as a real 4DHumans user's file would give them to the method.
    """
    import tempfile
    from pathlib import Path

    from multithumbs.perception.appearance import fill_appearance
    from multithumbs.perception.model_keypoints import reproject_model_keypoints
    from multithumbs.perception.phalp import load_phalp
    from multithumbs.perception.phalp_export import export_phalp

    shots = video.truth.world.shots()
    with tempfile.TemporaryDirectory(prefix="mt_phalp_") as tmp:
        path = export_phalp(Path(tmp) / "results.pkl", tracks, shots, body)
        imported = load_phalp(path, shots, video.truth.world.image_size, trust=True, video_name="video")
    read = reproject_model_keypoints(list(imported.tracks), video.truth.world.K[0], body)
    return fill_appearance(read, video.frames, imported.uv_appearance, imported.uv_valid)


__all__ = ["BACKENDS", "PERCEPTION_ROUTES", "INPUT_SOURCES", "PIXEL_BACKENDS", "PIXEL_STAGES", "InputCache",
           "checked_pixel_stages", "pixel_input_params", "pixel_inputs", "through_phalp_file"]
