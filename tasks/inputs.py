"""Tasks that produce a video's per-shot inputs: shots, people, camera trajectories, shared spaces.

From a real video: :func:`detect_video_shots` (scenedetect), :func:`perceive_people` (a perception spec,
e.g. a 4DHumans/PHALP results file), :func:`track_shot_camera` and :func:`shared_space` (pycolmap).

``simulate_inputs`` synthesises a scene and SIMULATES the inputs from its ground truth (the benchmark's
stand-ins for 4DHumans, DROID-SLAM and VGGT; labelled as simulated in every artifact and report).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Callable

import numpy as np
from prefect import task
from prefect.cache_policies import NO_CACHE

from storage.codecs import encode
from storage.keys import artifact_key
from storage.store import ArtifactRef, CorruptArtifact
from tasks.artifacts import STAGE_VERSIONS, cached_stage, compute_fixed, load, open_store, stage_key, stage_task


@task(name="simulate_inputs", cache_policy=NO_CACHE, retries=1)
def simulate_inputs(store_url: str, scene: dict, out_dir: str | None = None, smpl_model: str | None = None,
                    body: dict[str, str] | None = None) -> dict[str, Any]:
    """Synthesise a scene and its SIMULATED per-shot inputs; artifacts for truth, shots, tracks, cameras, spaces.

    Also writes the scene's files (video, ground truth, contact sheet) into ``out_dir`` when given.
    The scene is rendered only when one of its artifacts is missing. The people are ``smpl_model``'s
    bodies (None: the procedural body) and ``body`` its identity (:func:`tasks.body.resolve_body`),
    hashed into the keys.
    """
    from multithumbs.synth.config import config_from_json

    config = config_from_json(scene)
    store = open_store(store_url)
    params = {"scene": scene, **(body or {})}
    n_cuts = config.num_shots - 1
    names = ["truth", "shots", *(f"tracks_{k}" for k in range(config.num_shots)),
             *(f"trajectory_{k}" for k in range(config.num_shots)), *(f"space_{c}" for c in range(n_cuts))]
    keys = {n: artifact_key("simulate_inputs", STAGE_VERSIONS["simulate_inputs"], {**params, "part": n}, [])
            for n in names}
    want_files = out_dir is not None and not (Path(out_dir) / "video.mp4").exists()
    if not want_files and all(store.exists(k) for k in keys.values()):
        return {n: ArtifactRef(k, "simulate_inputs", store_url) for n, k in keys.items()}

    from multithumbs.body.model import load_body_model
    from multithumbs.determinism import fix_threads
    from multithumbs.synth.files import write_synthetic
    from multithumbs.synth.perception import simulate_perception
    from multithumbs.synth.scene import synthesize
    from multithumbs.synth.simulated_geometry import simulate_camera_trajectory, simulate_shared_space

    fix_threads()  # the rounding depends on the thread count (tasks.artifacts.compute_fixed)
    body_model = load_body_model(smpl_model)
    video = synthesize(config, body_model)
    if out_dir is not None:
        write_synthetic(out_dir, video)
    shots = video.truth.world.shots()
    tracks = simulate_perception(video, body_model)
    parts = {"truth": video.truth, "shots": shots,
             **{f"tracks_{k}": t for k, t in enumerate(tracks)},
             **{f"trajectory_{k}": simulate_camera_trajectory(video, k) for k in range(config.num_shots)},
             **{f"space_{c}": simulate_shared_space(video, c) for c in range(n_cuts)}}
    refs = {}
    for name, value in parts.items():
        arrays, attributes = encode(value)
        attributes["provenance"] = {"params": {**params, "part": name}, "simulated": True}
        refs[name] = store.write(keys[name], "simulate_inputs", arrays, attributes)
    return refs


# ----------------------------------------------------------------------------------------------------
# Inputs from a real video: shots (scenedetect), perception (a spec), camera trajectories and shared
# spaces (pycolmap). Keys hash the video's bytes, never its path: a moved or renamed video is still cached.


def _parts(stage: str, compute: Callable[[], list], store_url: str, params: dict, inputs: dict[str, ArtifactRef],
           count: int) -> list[ArtifactRef]:
    """Like :func:`tasks.artifacts.cached_stage` for a stage with ``count`` outputs (one artifact each)."""
    store = open_store(store_url)
    keys = [stage_key(stage, {**params, "part": k}, inputs) for k in range(count)]
    if all(store.exists(k) for k in keys):
        try:
            for key in keys:
                store.read(key)
            return [ArtifactRef(k, stage, store_url) for k in keys]
        except CorruptArtifact:
            pass
    values = compute_fixed(compute)
    if len(values) != count:
        raise RuntimeError(f"stage {stage}: computed {len(values)} parts, expected {count}")
    refs = []
    for part, (key, value) in enumerate(zip(keys, values)):
        if store.exists(key):
            try:
                store.read(key)
                refs.append(ArtifactRef(key, stage, store_url))
                continue
            except CorruptArtifact:
                store.delete(key)
        arrays, attributes = encode(value)
        attributes["provenance"] = {"params": {**params, "part": part}, "inputs": {k: r.key for k, r in inputs.items()}}
        refs.append(store.write(key, stage, arrays, attributes))
    return refs


def spec_fingerprint(spec: str) -> str:
    """The perception spec with every file it names replaced by the digest of the file's bytes."""
    from storage.keys import file_digest

    def digest(text: str) -> str:
        return f"sha256:{file_digest(text)}" if text and Path(text).is_file() else text

    out = []
    for term in spec.split("+"):
        backend, sep, argument = term.partition(":")
        parts = [f"{k}={digest(v)}" if eq else digest(k)
                 for k, eq, v in (p.partition("=") for p in argument.split(","))] if argument else []
        out.append(backend + sep + ",".join(parts))
    return "+".join(out)


@stage_task("shots")
def detect_video_shots(store_url: str, inputs: dict[str, ArtifactRef], params: dict, video_path: str) -> ArtifactRef:
    """Cuts of the video by scenedetect (params: ``video`` digest, ``config`` of :class:`ShotConfig`)."""
    def compute():
        from multithumbs.scene.shots import ShotConfig, detect_shots

        return detect_shots(video_path, ShotConfig(**params["config"]))
    return cached_stage("shots", compute, store_url, params, inputs)


@stage_task("shots")
def given_shots(store_url: str, inputs: dict[str, ArtifactRef], params: dict) -> ArtifactRef:
    """Shots from known cut frames (params: ``video`` digest, ``cuts``, ``num_frames``, ``fps``)."""
    def compute():
        import numpy as np

        from multithumbs.types import Shots

        n = params["num_frames"]
        return Shots(np.asarray(params["cuts"], np.int64), params["fps"], n, np.zeros(n), "given")
    return cached_stage("shots", compute, store_url, params, inputs)


@task(name="perception", cache_policy=NO_CACHE, retries=1)
def perceive_people(store_url: str, inputs: dict[str, ArtifactRef], params: dict, video_path: str,
                    spec: str, smpl_model: str | None = None, device: str = "auto") -> list[ArtifactRef]:
    """Per-shot :class:`PersonTracks` from the perception ``spec`` (params: ``video`` digest, ``spec``
    fingerprint, ``trust``, ``K`` the method's intrinsics that model-derived keypoints are reprojected
    through, and the ``body`` identity that poses them); one artifact per shot. ``device`` (``"auto"``: CUDA
    when present) is not part of the key: it changes where the networks run, not what they are."""
    shots = load(inputs["shots"])

    def compute():
        import numpy as np

        from multithumbs.body.model import load_body_model
        from multithumbs.perception import load_perception

        from tasks.progress import stage_progress

        K = None if params.get("K") is None else np.asarray(params["K"], np.float64)
        source = spec.split("+")[0].split(":")[0]
        return load_perception(spec, video_path, shots, trust=params["trust"], intrinsics=K,
                               body=load_body_model(smpl_model), device=device,
                               progress=stage_progress(f"perception: {source} on {shots.num_frames} frames",
                                                       shots.num_frames, lambda label: label.startswith(source)))
    return _parts("perception", compute, store_url, params, inputs, shots.num_shots)


@stage_task("focal")
def estimate_video_focal(store_url: str, inputs: dict[str, ArtifactRef], params: dict, video_path: str) -> ArtifactRef:
    """The video's focal length when nobody gave it (:mod:`multithumbs.scene.focal`). Inputs ``shots`` only:
    the estimate from the frames alone, straight edges or a moving camera (a :class:`FocalEstimate` whose
    source is ``none`` when neither gives one); with ``motion`` (that answer) and ``tracks_<k>`` too: the final
    estimate (the frames', else people's heights, else the default). Params: ``video`` digest, ``config`` of :class:`FocalConfig`."""
    def compute():
        from multithumbs.scene.focal import FocalConfig, FocalEstimate, estimate_focal, frames_estimate
        from multithumbs.video import read_frames

        shots, config = load(inputs["shots"]), _config(FocalConfig, params["config"])
        if "motion" not in inputs:
            estimate, why = frames_estimate(read_frames(video_path), shots.ranges, None, config)
            return estimate or FocalEstimate(0.0, "none", why)
        motion = load(inputs["motion"])
        if motion.source != "none":
            return motion
        tracks = [load(inputs[f"tracks_{k}"]) for k in range(shots.num_shots)]
        h, w = tracks[0].image_size
        return estimate_focal(np.zeros((0, h, w, 3), np.uint8), shots.ranges, tracks=tracks, config=config,
                              from_frames=(None, motion.detail))
    return cached_stage("focal", compute, store_url, params, inputs)


def _union_masks(tracks, frames: list[int]) -> dict[int, np.ndarray]:
    """Video frame -> ``(H, W)`` bool union of the shot's people masks."""
    union = tracks.people_mask(np.asarray(frames, int) - tracks.start_frame)
    return dict(zip(frames, union))


@stage_task("trajectory")
def track_shot_camera(store_url: str, inputs: dict[str, ArtifactRef], params: dict, video_path: str) -> ArtifactRef:
    """The camera trajectory of one shot with people masked out (inputs: ``shots``, ``tracks``; params:
    ``video`` digest, ``shot``, ``K``, ``config`` of :class:`TrackingConfig`)."""
    def compute():
        from multithumbs.scene.tracking import TrackingConfig, track_camera
        from multithumbs.video import iter_frames

        shots, tracks = load(inputs["shots"]), load(inputs["tracks"])
        a, b = shots.ranges[params["shot"]]
        frames = np.stack(list(iter_frames(video_path, a, b)))
        masks = _union_masks(tracks, list(range(a, b)))
        return track_camera(frames, np.asarray(params["K"]), np.stack([masks[f] for f in range(a, b)]),
                            params["shot"], a, _config(TrackingConfig, params["config"]))
    return cached_stage("trajectory", compute, store_url, params, inputs)


@stage_task("space")
def shared_space(store_url: str, inputs: dict[str, ArtifactRef], params: dict, video_path: str) -> ArtifactRef:
    """The shared space at one cut (inputs: ``shots``, ``tracks_before``, ``tracks_after``,
    ``trajectory_before``, ``trajectory_after``; params: ``video`` digest, ``cut``, ``K``, ``config`` of
    :class:`TwoViewConfig`, ``neighbour_frames``)."""
    def compute():
        from multithumbs.scene.geometry import cut_frames_needed, cut_shared_space
        from multithumbs.scene.two_view_pose import TwoViewConfig
        from multithumbs.video import read_frames

        shots, c = load(inputs["shots"]), params["cut"]
        static = all(load(inputs[k]).source == "static" for k in ("trajectory_before", "trajectory_after"))
        needed = cut_frames_needed(shots, c, static, params["neighbour_frames"])
        frames = dict(zip(needed, read_frames(video_path, needed)))
        before, after = load(inputs["tracks_before"]), load(inputs["tracks_after"])
        masks = {**_union_masks(before, [f for f in needed if f < shots.cut_frames[c]]),
                 **_union_masks(after, [f for f in needed if f >= shots.cut_frames[c]])}
        K_all = np.broadcast_to(np.asarray(params["K"]), (shots.num_frames, 3, 3))
        return cut_shared_space(shots, c, frames, K_all, masks, _config(TwoViewConfig, params["config"]))
    return cached_stage("space", compute, store_url, params, inputs)


def _config(cls, values: dict):
    return cls(**{k: tuple(v) if isinstance(v, list) else v for k, v in values.items()})


@task(name="ground_truth", cache_policy=NO_CACHE, retries=1)
def import_ground_truth(store_url: str, truth_path: str) -> ArtifactRef:
    """A ground-truth ``.npz`` as an artifact keyed by its bytes (for evaluation and the outputs' truth panel)."""
    from storage.keys import file_digest

    params = {"file": file_digest(truth_path)}

    def compute():
        from multithumbs.io import load_ground_truth

        return load_ground_truth(truth_path)[0]
    return cached_stage("ground_truth", compute, store_url, params, {})
