"""The evaluation flow: metrics of a result file against ground truth, as dashboard table and markdown."""

from __future__ import annotations

from typing import Any

from prefect import flow, task
from prefect.artifacts import create_markdown_artifact, create_table_artifact
from prefect.cache_policies import NO_CACHE

from flows.reconstruct import metrics_rows


@task(name="evaluate-files", cache_policy=NO_CACHE)
def evaluate_files(result_path: str, truth_path: str) -> dict[str, Any]:
    """Every metric of METRICS.md for a result ``.npz`` against a ground-truth ``.npz``."""
    import json

    from multithumbs.body.model import load_body_model
    from multithumbs.io import load_ground_truth, load_result
    from multithumbs.metrics.evaluate import evaluate

    metrics = evaluate(load_result(result_path), load_ground_truth(truth_path)[0], load_body_model())
    return json.loads(json.dumps(metrics, default=lambda o: o.tolist() if hasattr(o, "tolist") else str(o)))


@flow(name="evaluate")
def evaluate(result_path: str, truth_path: str) -> dict[str, Any]:
    """Score ``result_path`` against ``truth_path``; the metrics table and a markdown summary go to the dashboard."""
    metrics = evaluate_files(result_path, truth_path)
    rows = metrics_rows(metrics)
    create_table_artifact(key="evaluation", table=rows, description=f"{result_path} vs {truth_path}")
    value = lambda v: f"{v:.3f}" if isinstance(v, (int, float)) else str(v)
    lines = [f"# Evaluation of `{result_path}`", "", f"Ground truth `{truth_path}`.", "", "| metric | value | unit |",
             "|---|---|---|", *(f"| {r['metric']} | {value(r['value'])} | {r['unit']} |" for r in rows
                                 if r["value"] is not None)]
    create_markdown_artifact(key="evaluation-report", markdown="\n".join(lines) + "\n")
    return metrics
