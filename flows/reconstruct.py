"""Reconstruction flows: every stage a cached task, cuts aligned in parallel (DESIGN §6)."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

from prefect import flow
from prefect.artifacts import create_markdown_artifact, create_table_artifact
from prefect.task_runners import ThreadPoolTaskRunner

from flows.method import run_method, space_refs
from multithumbs.metric_names import METRIC_KEYS
from storage.store import ArtifactRef
from tasks.evaluation import evaluate_result
from tasks.inputs import simulate_inputs
from tasks.outputs import write_outputs
from tasks.method import method_params

METRIC_ORDER = (*METRIC_KEYS, "w_mpjpe_track", "wa_mpjpe_track", "accel_world", "ids_total", "ate_alignment")
"""Per-video table columns: the headline metrics in the paper's order (:data:`multithumbs.bench.METRIC_KEYS`),
this project's own variants, and how the video's ATE was aligned."""


def metrics_rows(metrics: dict[str, Any]) -> list[dict[str, Any]]:
    """The metrics as table rows ``metric, value, unit``: the headline ones in the paper's order, then this
    project's own, then how each ATE was aligned (:func:`multithumbs.metrics.evaluate.report_rows`)."""
    from multithumbs.metric_names import report_rows

    return report_rows(metrics)


def publish_outputs(out_dir: str | Path, name: str, variant: str, video_path: str, method_refs: dict[str, ArtifactRef],
                    spaces: list[ArtifactRef], truth: ArtifactRef | None, metrics: dict[str, Any] | None,
                    run_info: dict[str, Any], smpl_model: str | None = None) -> dict[str, str]:
    """Write the video's outputs (:func:`tasks.outputs.write_outputs`, posed with ``smpl_model``) and put
    its report and metrics table in the dashboard."""
    files = write_outputs(str(out_dir), name, variant, video_path, method_refs, spaces, truth, metrics, run_info,
                          smpl_model)
    publish_report(name, variant, files, metrics)
    return files


def publish_report(name: str, variant: str, files: dict[str, str], metrics: dict[str, Any] | None) -> None:
    """The video's metrics table and markdown report as dashboard artifacts."""
    if metrics is not None:
        create_table_artifact(key="metrics", table=metrics_rows(metrics), description=f"{name} ({variant})")
    if "report" in files:
        create_markdown_artifact(key="reconstruction-report", markdown=Path(files["report"]).read_text(),
                                 description=f"{name} ({variant})")


SIMULATED_BACKENDS = {"shots": "ground truth cuts", "perception": "SIMULATED (synth/perception.py)",
                      "camera tracking": "SIMULATED (stands in for DROID-SLAM)",
                      "shared space": "SIMULATED (stands in for VGGT)"}


@flow(name="reconstruct-synthetic", task_runner=ThreadPoolTaskRunner(max_workers=2))
def reconstruct_synthetic(scene: dict | str, out_dir: str, store_url: str, variant: str = "full",
                          method: dict[str, Any] | None = None, smpl_model: str | None = None) -> dict[str, Any]:
    """Synthesise a scene (with SIMULATED perception, shared space and camera tracking), reconstruct it with
    the method's stages as cached tasks, score it, and write ``result.npz`` and ``metrics.json`` to ``out_dir``.

    Args:
        scene: a :class:`~multithumbs.synth.scene.SceneConfig` as JSON (``config_to_json``), or the name of
            a scene of the standard suite (``s09_crossing_at_cut``): that scene exactly, as ``multithumbs demo``.
        out_dir: folder for the scene's files and the result.
        store_url: artifact store (local path or fsspec URL).
        variant: method variant (``full``, an ablation or a baseline).
        method: parameter overrides, e.g. ``{"reid": {"max_distance": 0.8}}`` (:func:`tasks.method.method_config`).
        smpl_model: the SMPL file (.npz or .pkl) the scene is synthesised with and every stage poses; default
            ``$MULTITHUMBS_SMPL_MODEL``, else the procedural body (:func:`tasks.body.resolve_body`).
    """
    from tasks.body import resolve_body

    if isinstance(scene, str):
        from multithumbs.synth.config import config_to_json
        from multithumbs.synth.suite import suite_scene

        scene = config_to_json(suite_scene("standard", scene))
    body_path, body = resolve_body(smpl_model)
    Path(out_dir).mkdir(parents=True, exist_ok=True)
    timings: dict[str, float] = {}
    start = time.perf_counter()
    refs = simulate_inputs(store_url, scene, out_dir, body_path, body)
    timings["synthesis and simulated inputs"] = time.perf_counter() - start
    (method_refs,) = run_method(store_url, [(refs, method_params(variant, method, body))], timings, body_path)
    metrics = evaluate_result(method_refs["result"], refs["truth"], body_path)
    publish_outputs(out_dir, scene.get("name", "scene"), variant, str(Path(out_dir) / "video.mp4"), method_refs,
                    space_refs(refs),
                    refs["truth"], metrics, {"backends": SIMULATED_BACKENDS, "timings": timings, "variant": variant,
                                             "body_model": body_path or "procedural"}, body_path)
    return metrics
