"""The synthetic benchmark: every scene of a suite through the full method, its ablations and baselines.

Per scene: synthesise, simulate perception, the shared space at each cut and each shot's camera
tracking (SIMULATED backends, labelled so in the report), then run every variant — sharing what they
have in common: one alignment per distinct alignment setting, one propagation per distinct alignment and
propagation setting, one post-processing per distinct placement, identities and post setting — and
score each with :func:`multithumbs.metrics.evaluate.evaluate`. Scenes run in parallel worker processes.

Aggregation over scenes: pose errors (W-MPJPE, WA-MPJPE, MPJPE, PA-MPJPE, MPVPE, Accel and their
``_track``/``_world`` variants, FS with truth) are weighted by each scene's scored frames (docs/METRICS.md);
ATE, IDs, PCK*, Jitter and FS are means over scenes (ATE per sequence as DROID-SLAM and TRAM), and the
switch counts also have a total.
"""

from __future__ import annotations

import math
import os
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass, field
from typing import Any, Callable, Sequence

import numpy as np

from multithumbs.bench_sources import (BACKENDS, INPUT_SOURCES, PERCEPTION_ROUTES, PIXEL_BACKENDS,  # noqa: F401
                                       PIXEL_STAGES, InputCache, checked_pixel_stages, pixel_input_params,
                                       pixel_inputs,
                                       through_phalp_file)
from multithumbs.errors import InputError
from multithumbs.metric_names import METRIC_KEYS  # noqa: F401  (re-exported)
from multithumbs.pipeline import (VARIANTS, MethodConfig, Placement, align_cuts, post_processed_world, prepare_inputs,
                                  propagate, reidentify, to_world_result, variant_config, world_diagnostics)
from multithumbs.synth.scene import SceneConfig, config_to_json

EXTRA_KEYS = ("w_mpjpe_track", "wa_mpjpe_track", "accel_world", "fs_gt", "fs_truth", "ate_mean", "ids_total",
              "ids_within_shots", "coverage")
"""This project's own variants and diagnostics, reported beside the headline metrics."""
LABEL_KEYS = ("ate_alignment", "ids_at_cuts")
"""Per-scene values that are not numbers: the alignment each ATE used, the switches through each cut."""
FRAME_WEIGHTED = ("w_mpjpe", "wa_mpjpe", "mpjpe", "pa_mpjpe", "mpvpe", "accel", "w_mpjpe_track", "wa_mpjpe_track",
                  "accel_world", "fs_gt")
SUMMED = ("ids_total", "ids_within_shots")
"""Metrics that also get a ``total`` over scenes."""


@dataclass(frozen=True)
class SceneScores:
    """Metrics of every variant on one scene.

    Attributes:
        scene: scene name.
        metrics: variant -> metric name -> value (plus ``scored_frames``).
        seconds: variant -> wall time of its own stages (shared stages counted where first run).
        labels: variant -> :data:`LABEL_KEYS` name -> value (the single sequence's entry).
        backends: input stage -> what produced it for this scene.
        stage_seconds: input stage -> wall seconds (pixel inputs; empty when simulated).
    """

    scene: str
    metrics: dict[str, dict[str, float]]
    seconds: dict[str, float]
    labels: dict[str, dict[str, Any]] = field(default_factory=dict)
    backends: dict[str, str] = field(default_factory=dict)
    stage_seconds: dict[str, float] = field(default_factory=dict)


def _alignment_key(config: MethodConfig) -> tuple:
    return (config.independent_shots, config.skip_align, config.align)


def run_scene_results(config: SceneConfig, variants: Sequence[str], body, base: MethodConfig = MethodConfig(),
                      seed: int = 0, seconds: dict[str, float] | None = None, perception: str = "direct",
                      inputs: str = "simulated", stages: dict[str, Any] | None = None,
                      pixel_stages: Sequence[str] = PIXEL_STAGES, input_cache: InputCache | None = None):
    """Synthesise one scene and run the variants on shared stages (module docstring); ``perception`` is
    one of :data:`PERCEPTION_ROUTES` (simulated inputs only), ``inputs`` one of :data:`INPUT_SOURCES`;
    ``stages`` (when given) receives ``"backends"`` and ``"seconds"`` of the input stages; with pixel
    inputs, ``pixel_stages`` are computed from the frames and the others simulated (:func:`pixel_inputs`),
    and kept in ``input_cache`` (when given) for the next run.

    Returns:
        the scene's :class:`~multithumbs.types.GroundTruth` and variant -> its
        :class:`~multithumbs.types.WorldResult`; ``seconds`` (when given) receives each variant's wall time.
    """
    import time

    from multithumbs.determinism import fix_threads
    from multithumbs.synth.perception import simulate_perception
    from multithumbs.synth.scene import synthesize
    from multithumbs.synth.simulated_geometry import simulate_camera_trajectory, simulate_shared_space

    fix_threads()  # synthesis and simulated perception round by thread count too, not only the method
    video = synthesize(config, body)
    if inputs in ("pixels", "pixels_no_focal"):
        params = pixel_input_params(config_to_json(config), pixel_stages, inputs == "pixels_no_focal", seed)
        cached = input_cache.load(params) if input_cache is not None else None
        if cached is not None:
            shots, tracks, trajectories, spaces, backends, stage_seconds = cached
            backends = {**backends, "inputs": "kept from an earlier run"}
        else:
            stage_seconds: dict[str, float] = {}
            shots, tracks, trajectories, spaces, backends = pixel_inputs(video, body, stage_seconds,
                                                                         withhold_focal=inputs == "pixels_no_focal",
                                                                         stages=pixel_stages, seed=seed)
            if input_cache is not None:
                input_cache.save(params, (shots, tracks, trajectories, spaces, backends, stage_seconds))
        if stages is not None:
            stages.update(backends=backends, seconds=stage_seconds)
    elif inputs != "simulated":
        raise InputError(f"inputs {inputs!r}: expected one of {', '.join(INPUT_SOURCES)}")
    else:
        shots = video.truth.world.shots()
        tracks = simulate_perception(video, body, seed=seed)
        if perception == "phalp":
            tracks = through_phalp_file(tracks, video, body)
        elif perception != "direct":
            raise InputError(f"perception route {perception!r}: expected one of {', '.join(PERCEPTION_ROUTES)}")
        spaces = [simulate_shared_space(video, c, seed=seed) for c in range(len(shots.cut_frames))]
        trajectories = [simulate_camera_trajectory(video, k, seed=seed) for k in range(shots.num_shots)]
        if stages is not None:
            stages.update(backends=dict(BACKENDS), seconds={})
    tracks = prepare_inputs(shots, tracks, trajectories, spaces)
    aligned_cache: dict[tuple, list] = {}
    placement_cache: dict[tuple, Placement] = {}
    world_cache: dict[tuple, tuple] = {}
    results = {}
    for name in variants:
        cfg = variant_config(name, base)
        start = time.perf_counter()
        key = _alignment_key(cfg)
        if key not in aligned_cache:
            aligned_cache[key] = align_cuts(shots, tracks, spaces, body, cfg)
        aligned = aligned_cache[key]
        key += (cfg.propagate_orientation,)
        if key not in placement_cache:
            placement_cache[key] = propagate(shots, tracks, trajectories, aligned, body,
                                             independent=cfg.independent_shots,
                                             propagate_orientation=cfg.propagate_orientation)
        placement = placement_cache[key]
        ids = reidentify(tracks, placement, cfg.reid, cfg.appearance_window, shots.fps)
        # Variants whose identities agree share the post-processed world (baselines often agree with full).
        key += (tuple(g.tobytes() for g in ids.global_ids), ids.matched_at_cut.tobytes(), cfg.skip_post, cfg.post)
        if key not in world_cache:
            world_cache[key] = post_processed_world(shots, tracks, placement, ids, body, cfg)
        world, _ = world_cache[key]
        results[name] = to_world_result(shots, tracks, world, ids, world_diagnostics(aligned, placement, ids))
        if seconds is not None:
            seconds[name] = time.perf_counter() - start
    return video.truth, results


def run_scene(config: SceneConfig, variants: Sequence[str] = VARIANTS, base: MethodConfig = MethodConfig(),
              seed: int = 0, perception: str = "direct", inputs: str = "simulated",
              pixel_stages: Sequence[str] = PIXEL_STAGES, input_cache: InputCache | None = None) -> SceneScores:
    """Synthesise one scene, run the variants on shared stages, score them."""
    from multithumbs.body.model import load_body_model
    from multithumbs.metrics.evaluate import evaluate

    body = load_body_model()
    seconds: dict[str, float] = {}
    stages: dict[str, Any] = {}
    truth, results = run_scene_results(config, variants, body, base, seed, seconds, perception, inputs, stages,
                                       pixel_stages, input_cache)
    metrics, labels = {}, {}
    for name, result in results.items():
        metrics[name], labels[name] = scene_metrics(evaluate(result, truth, body))
    return SceneScores(config.name, metrics, seconds, labels, stages.get("backends", {}), stages.get("seconds", {}))


def scene_metrics(report: dict) -> tuple[dict[str, float], dict[str, Any]]:
    """The numbers and labels the bench keeps from one scene's evaluation report."""
    numbers = {k: _float(report.get(k)) for k in (*METRIC_KEYS, *EXTRA_KEYS, "scored_frames")}
    return numbers, {k: report[k][0] for k in LABEL_KEYS if report.get(k)}


def _float(value) -> float:
    try:
        return float(value)
    except (TypeError, ValueError):
        return float("nan")


def _init_worker(threads: int) -> None:
    from multithumbs.determinism import fix_threads

    fix_threads(threads)


def run_suite(configs: Sequence[SceneConfig], variants: Sequence[str] = VARIANTS, workers: int | None = None,
              base: MethodConfig = MethodConfig(),
              progress: Callable[[SceneScores, int, int], None] | None = None,
              perception: str = "direct", inputs: str = "simulated",
              pixel_stages: Sequence[str] = PIXEL_STAGES, input_cache: InputCache | None = None) -> list[SceneScores]:
    """Run every scene (in ``workers`` processes; default: one per core) and return their scores in order;
    ``perception``, ``inputs``, ``pixel_stages`` and ``input_cache`` (picklable) as :func:`run_scene_results`."""
    for v in variants:
        variant_config(v)  # unknown names fail before any work
    if inputs not in INPUT_SOURCES:
        raise InputError(f"inputs {inputs!r}: expected one of {', '.join(INPUT_SOURCES)}")
    pixel_stages = checked_pixel_stages(pixel_stages)
    if perception not in PERCEPTION_ROUTES:
        raise InputError(f"--perception-file {perception!r}: expected one of {', '.join(PERCEPTION_ROUTES)}")
    workers = workers or max(1, min(len(configs), os.cpu_count() or 1))
    if workers == 1:
        out = []
        for i, c in enumerate(configs):
            out.append(run_scene(c, variants, base, perception=perception, inputs=inputs, pixel_stages=pixel_stages,
                                 input_cache=input_cache))
            if progress:
                progress(out[-1], i + 1, len(configs))
        return out
    results: dict[str, SceneScores] = {}
    # One torch thread per worker: the optimisations are small-op bound, processes scale better.
    with ProcessPoolExecutor(workers, initializer=_init_worker, initargs=(1,)) as pool:
        futures = {pool.submit(run_scene, c, variants, base, 0, perception, inputs, pixel_stages, input_cache): c.name
                   for c in configs}
        for done, future in enumerate(as_completed(futures), 1):
            scores = future.result()
            results[scores.scene] = scores
            if progress:
                progress(scores, done, len(configs))
    return [results[c.name] for c in configs]


def summarize(scenes: Sequence[SceneScores], variants: Sequence[str] = VARIANTS) -> dict:
    """variant -> metric -> ``{"per_scene": {scene: value}, "mean": value}`` (module docstring: aggregation).

    :data:`SUMMED` metrics also get ``"total"``; :data:`LABEL_KEYS` only ``"per_scene"``.
    """
    out: dict = {}
    for v in variants:
        out[v] = {}
        for key in (*METRIC_KEYS, *EXTRA_KEYS):
            per_scene = {s.scene: s.metrics[v][key] for s in scenes}
            values = np.array(list(per_scene.values()), dtype=float)
            if key in FRAME_WEIGHTED:
                weights = np.array([s.metrics[v]["scored_frames"] for s in scenes], dtype=float)
                ok = np.isfinite(values) & (weights > 0)
                mean = float((values[ok] * weights[ok]).sum() / weights[ok].sum()) if ok.any() else math.nan
            else:
                ok = np.isfinite(values)
                mean = float(values[ok].mean()) if ok.any() else math.nan
            out[v][key] = {"per_scene": per_scene, "mean": mean}
            if key in SUMMED:
                out[v][key]["total"] = float(values[np.isfinite(values)].sum())
        for key in LABEL_KEYS:
            out[v][key] = {"per_scene": {s.scene: s.labels.get(v, {}).get(key) for s in scenes}}
        out[v]["seconds"] = {s.scene: s.seconds[v] for s in scenes}
    return out


def check_variants(names: Sequence[str]) -> list[str]:
    """Validate variant names for the CLI."""
    unknown = [n for n in names if n not in VARIANTS]
    if unknown:
        raise InputError(f"--variants: unknown {unknown[0]!r}; choose from {', '.join(VARIANTS)}")
    return list(names)
