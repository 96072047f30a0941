"""The benchmark flow: a synthetic suite through every variant, shared stages computed once (DESIGN §6)."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any, Sequence

from prefect import flow
from prefect.artifacts import create_markdown_artifact, create_progress_artifact, create_table_artifact, \
    update_progress_artifact

from flows.method import run_method
from flows.runners import make_task_runner
from tasks.evaluation import evaluate_result
from tasks.inputs import simulate_inputs
from tasks.method import method_params


@flow(name="benchmark-run")
def _benchmark_run(scenes: list[dict], variants: list[str], store_url: str) -> dict[str, Any]:
    from multithumbs.bench import SceneScores, scene_metrics, summarize

    progress = create_progress_artifact(progress=0.0, description=f"{len(scenes)} scenes x {len(variants)} variants")
    refs = [f.result() for f in [simulate_inputs.submit(store_url, scene) for scene in scenes]]
    update_progress_artifact(progress, 25.0)
    jobs = [(r, method_params(v)) for r in refs for v in variants]
    results = [out["result"] for out in run_method(store_url, jobs)]
    update_progress_artifact(progress, 85.0)
    futures = [evaluate_result.submit(res, job[0]["truth"]) for res, job in zip(results, jobs)]
    scores = []
    for i, scene in enumerate(scenes):
        metrics, labels = {}, {}
        for j, v in enumerate(variants):
            metrics[v], labels[v] = scene_metrics(futures[i * len(variants) + j].result())
        scores.append(SceneScores(scene["name"], metrics, {v: math.nan for v in variants}, labels))
    update_progress_artifact(progress, 100.0)
    return summarize(scores, variants)


@flow(name="benchmark")
def benchmark(suite: str = "standard", variants: Sequence[str] | None = None, scenes: Sequence[str] | None = None,
              store_url: str = "benchmark/store", out_dir: str = "benchmark", runner: str = "threads",
              workers: int = 2, scene_configs: list[dict] | None = None) -> dict[str, Any]:
    """Run a synthetic suite's scenes through the method's variants (SIMULATED perception, shared space and
    camera tracking); write ``bench.json`` (variant -> metric -> per-scene values and mean) and ``bench.md``.

    Args:
        suite: suite name (``multithumbs suite`` lists them). variants: default all. scenes: default all.
        store_url: artifact store; variants share the stages they have in common through it.
        out_dir: where ``bench.json`` and ``bench.md`` go.
        runner, workers: task runner (:func:`flows.runners.make_task_runner`).
        scene_configs: scenes as SceneConfig JSON instead of a suite's (``suite`` and ``scenes`` then unused).
    """
    from multithumbs.bench import EXTRA_KEYS, METRIC_KEYS, check_variants
    from multithumbs.pipeline import VARIANTS
    from multithumbs.synth.config import config_to_json
    from multithumbs.synth.suite import suite as suite_configs, suite_scene

    variants = check_variants(list(variants or VARIANTS))
    if scene_configs:
        configs = list(scene_configs)
    else:
        configs = [config_to_json(c) for c in
                   ([suite_scene(suite, s) for s in scenes] if scenes else suite_configs(suite))]
    summary = _benchmark_run.with_options(task_runner=make_task_runner(runner, workers))(configs, variants, store_url)
    columns = (*METRIC_KEYS, *EXTRA_KEYS)
    rows = [{"variant": v, **{k: summary[v][k]["mean"] for k in columns}, "ate_alignment": _alignments(summary[v])}
            for v in variants]
    create_table_artifact(key="benchmark", table=rows, description=f"suite {suite}: means over {len(configs)} scenes")
    lines = ["| variant | " + " | ".join(columns) + " | ate_alignment |", "|---|" + "---|" * (len(columns) + 1)]
    lines += ["| " + r["variant"] + " | " + " | ".join(f"{r[k]:.2f}" for k in columns) + f" | {r['ate_alignment']} |"
              for r in rows]
    markdown = (f"# Benchmark `{suite}` ({len(configs)} scenes)\n\nPerception, shared space and camera tracking "
                f"SIMULATED; cuts from ground truth.\n\n" + "\n".join(lines) + "\n")
    create_markdown_artifact(key="benchmark-report", markdown=markdown)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    (out / "bench.json").write_text(json.dumps(summary, indent=2, default=str))
    (out / "bench.md").write_text(markdown)
    return summary


def _alignments(variant_summary: dict[str, Any]) -> str:
    """How the scenes' ATE were aligned, counted: e.g. ``sim3_camera_centres: 4, sim3_people_joints: 8``."""
    counts: dict[str, int] = {}
    for label in variant_summary.get("ate_alignment", {}).get("per_scene", {}).values():
        counts[str(label)] = counts.get(str(label), 0) + 1
    return ", ".join(f"{k}: {n}" for k, n in sorted(counts.items()))
