"""One thin Prefect task per stage (DESIGN §6).

Every task takes the store's URL, its inputs as :class:`~storage.store.ArtifactRef` s and its parameters
as plain JSON, computes its artifact key from them (:func:`storage.keys.artifact_key`), and returns the
ref without computing when the store already holds that key: the store is the source of truth. The
same key is the task's Prefect ``cache_key_fn`` while the store holds it, so Prefect's cache and the
store agree, and a deleted or corrupt artifact is recomputed rather than served from Prefect's cache.
"""

from __future__ import annotations

import dataclasses
import functools
import json
from pathlib import Path
from typing import Any, Callable

from prefect import task
from prefect.cache_policies import NO_CACHE

from storage.codecs import decode, encode
from storage.keys import artifact_key
from storage.store import ArtifactRef, ArtifactStore, CorruptArtifact

STAGE_VERSIONS = {"simulate_inputs": 1, "align": 1, "finish": 1, "evaluate": 1}
"""Bump a stage's version when its code changes its output: its key and every key after it change."""


@functools.lru_cache(maxsize=8)
def open_store(url: str) -> ArtifactStore:
    return ArtifactStore(url)


def stage_key(stage: str, params: dict, inputs: dict[str, ArtifactRef]) -> str:
    return artifact_key(stage, STAGE_VERSIONS[stage], params, {k: r.key for k, r in sorted(inputs.items())})


def load(ref: ArtifactRef) -> Any:
    """The contract behind a ref."""
    return decode(*open_store(ref.store).read(ref.key))


def _cache_key(stage: str) -> Callable:
    def key_fn(context, parameters: dict) -> str | None:
        key = stage_key(stage, parameters["params"], parameters["inputs"])
        return key if open_store(parameters["store_url"]).exists(key) else None
    return key_fn


def cached_stage(stage: str, compute: Callable[[], Any], store_url: str, params: dict,
                 inputs: dict[str, ArtifactRef]) -> ArtifactRef:
    """Return the stage's artifact, computing and writing it only when the store lacks it (or it is corrupt)."""
    store = open_store(store_url)
    key = stage_key(stage, params, inputs)
    if store.exists(key):
        try:
            store.read(key)  # verify checksums: a corrupt artifact is recomputed, never trusted
            return ArtifactRef(key, stage, store_url)
        except CorruptArtifact:
            store.delete(key)
    arrays, attributes = encode(compute())
    attributes["provenance"] = {"params": params, "inputs": {k: r.key for k, r in inputs.items()}}
    return store.write(key, stage, arrays, attributes)


def stage_task(stage: str) -> Callable:
    """Decorate a stage function as a Prefect task with the store-backed cache key and I/O retries."""
    return task(name=stage, cache_key_fn=_cache_key(stage), persist_result=True, retries=2,
                retry_delay_seconds=1, retry_condition_fn=_retry_on_io)


def _retry_on_io(task, task_run, state) -> bool:
    try:
        state.result()
    except (OSError, TimeoutError):
        return True
    except Exception:
        return False
    return False


@task(name="simulate_inputs", cache_policy=NO_CACHE, retries=1)
def simulate_inputs(store_url: str, scene: dict, out_dir: str | None = None) -> dict[str, Any]:
    """Synthesise a scene and its SIMULATED per-shot inputs; artifacts for truth, shots, tracks, cameras, spaces.

    Also writes the scene's files (video, ground truth, contact sheet) into ``out_dir`` when given.
    The scene is rendered only when one of its artifacts is missing.
    """
    from multithumbs.synth.scene import config_from_json

    config = config_from_json(scene)
    store = open_store(store_url)
    params = {"scene": scene}
    n_cuts = config.num_shots - 1
    names = ["truth", "shots", *(f"tracks_{k}" for k in range(config.num_shots)),
             *(f"trajectory_{k}" for k in range(config.num_shots)), *(f"space_{c}" for c in range(n_cuts))]
    keys = {n: artifact_key("simulate_inputs", STAGE_VERSIONS["simulate_inputs"], {**params, "part": n}, [])
            for n in names}
    want_files = out_dir is not None and not (Path(out_dir) / "video.mp4").exists()
    if not want_files and all(store.exists(k) for k in keys.values()):
        return {n: ArtifactRef(k, "simulate_inputs", store_url) for n, k in keys.items()}

    from multithumbs.body.model import load_body_model
    from multithumbs.synth.files import write_synthetic
    from multithumbs.synth.perception import simulate_perception
    from multithumbs.synth.scene import synthesize
    from multithumbs.synth.simulated_geometry import simulate_camera_trajectory, simulate_shared_space

    body = load_body_model()
    video = synthesize(config, body)
    if out_dir is not None:
        write_synthetic(out_dir, video)
    shots = video.truth.world.shots()
    tracks = simulate_perception(video, body)
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


@stage_task("align")
def align_cut(store_url: str, inputs: dict[str, ArtifactRef], params: dict) -> ArtifactRef:
    """Scale and three-stage alignment at one cut (inputs: tracks_before, tracks_after, space)."""
    def compute():
        from multithumbs.body.model import load_body_model
        from multithumbs.method.align import AlignConfig, align_boundary
        from multithumbs.pipeline import boundary_people, sanitize_tracks

        body = load_body_model()
        config = AlignConfig(**{k: tuple(v) if isinstance(v, list) else v for k, v in params["align"].items()})
        people = boundary_people(sanitize_tracks(load(inputs["tracks_before"])),
                                 sanitize_tracks(load(inputs["tracks_after"])), body)
        return align_boundary(people, load(inputs["space"]), config, skip=params["skip"])
    return cached_stage("align", compute, store_url, params, inputs)


@stage_task("finish")
def finish(store_url: str, inputs: dict[str, ArtifactRef], params: dict) -> ArtifactRef:
    """Propagation, re-identification, assembly and post-processing (inputs: shots, tracks_k, trajectory_k, aligned_c)."""
    def compute():
        from multithumbs.body.model import load_body_model
        from multithumbs.pipeline import finish_video, sanitize_tracks, variant_config

        shots = load(inputs["shots"])
        tracks = [sanitize_tracks(load(inputs[f"tracks_{k}"])) for k in range(shots.num_shots)]
        trajectories = [load(inputs[f"trajectory_{k}"]) for k in range(shots.num_shots)]
        aligned = [load(inputs[f"aligned_{c}"]) for c in range(shots.num_shots - 1) if f"aligned_{c}" in inputs]
        return finish_video(shots, tracks, trajectories, aligned, load_body_model(), variant_config(params["variant"]))
    return cached_stage("finish", compute, store_url, params, inputs)


def method_params(variant: str) -> dict[str, dict]:
    """JSON parameters of the align and finish stages of a variant (what their keys hash)."""
    from multithumbs.pipeline import variant_config

    config = variant_config(variant)
    return {"align": {"align": dataclasses.asdict(config.align), "skip": config.skip_align},
            "finish": {"variant": variant, "reid": dataclasses.asdict(config.reid),
                       "post": dataclasses.asdict(config.post), "skip_post": config.skip_post,
                       "propagate_orientation": config.propagate_orientation}}


@task(name="evaluate", cache_policy=NO_CACHE)
def evaluate_result(result: ArtifactRef, truth: ArtifactRef) -> dict[str, Any]:
    """Every metric of METRICS.md for a result against ground truth (small: returned, not stored)."""
    from multithumbs.body.model import load_body_model
    from multithumbs.metrics.evaluate import evaluate

    metrics = evaluate(load(result), load(truth), load_body_model())
    return json.loads(json.dumps(metrics, default=lambda o: o.tolist() if hasattr(o, "tolist") else str(o)))
