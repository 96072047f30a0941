"""The dataset flow: many videos, each resumable from the store, one results table (DESIGN §6)."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from prefect import flow
from prefect.artifacts import create_progress_artifact, create_table_artifact, update_progress_artifact

from flows.method import run_method, space_refs
from flows.reconstruct import METRIC_ORDER, SIMULATED_BACKENDS, publish_report
from flows.runners import make_task_runner
from tasks.evaluation import evaluate_result
from tasks.inputs import simulate_inputs
from tasks.outputs import write_outputs
from tasks.method import method_params


def _item_name(item: dict[str, Any], index: int) -> str:
    return str(item.get("name") or item.get("scene", {}).get("name") or f"video{index:03d}")


def _check_items(items: list[dict[str, Any]]) -> list[str]:
    from multithumbs.errors import InputError

    if not items:
        raise InputError("dataset: no videos given")
    names = []
    for i, item in enumerate(items):
        if "scene" not in item:
            raise InputError(f"dataset item {i}: needs a 'scene' (a synthetic SceneConfig as JSON)")
        names.append(_item_name(item, i))
    if len(set(names)) != len(names):
        raise InputError("dataset: video names must be unique (each gets its own output folder)")
    return names


@flow(name="reconstruct-dataset-run")
def _dataset_run(items: list[dict[str, Any]], out_root: str, store_url: str, variant: str,
                 method: dict[str, Any] | None) -> list[dict[str, Any]]:
    names = _check_items(items)
    root = Path(out_root)
    progress = create_progress_artifact(progress=0.0, description=f"{len(items)} videos: inputs, method, evaluation")
    input_futures = []
    for name, item in zip(names, items):
        (root / name).mkdir(parents=True, exist_ok=True)
        input_futures.append(simulate_inputs.submit(store_url, item["scene"], str(root / name)))
    refs = [f.result() for f in input_futures]
    update_progress_artifact(progress, 30.0)
    params = method_params(variant, method)
    outs = run_method(store_url, [(r, params) for r in refs])
    update_progress_artifact(progress, 70.0)
    metric_futures = [evaluate_result.submit(out["result"], r["truth"]) for out, r in zip(outs, refs)]
    metrics = [f.result() for f in metric_futures]
    update_progress_artifact(progress, 80.0)
    output_futures = [write_outputs.submit(str(root / name), name, variant, str(root / name / "video.mp4"), out,
                                           space_refs(r), r["truth"], m, {"backends": SIMULATED_BACKENDS,
                                                                          "variant": variant})
                      for name, out, r, m in zip(names, outs, refs, metrics)]
    rows = []
    for name, out, m, future in zip(names, outs, metrics, output_futures):
        publish_report(name, variant, future.result(), m)
        rows.append({"video": name, **{k: m.get(k) for k in METRIC_ORDER}, "result": out["result"].key})
    update_progress_artifact(progress, 100.0)
    create_table_artifact(key="dataset-results", table=rows, description=f"{len(rows)} videos ({variant})")
    return rows


@flow(name="reconstruct-dataset")
def reconstruct_dataset(items: list[dict[str, Any]], out_root: str, store_url: str, variant: str = "full",
                        method: dict[str, Any] | None = None, runner: str = "threads", workers: int = 2
                        ) -> list[dict[str, Any]]:
    """Reconstruct and score many videos; write each one's outputs to ``out_root/NAME`` and the table to
    ``out_root/results.json`` and ``results.md``.

    Args:
        items: one dict per video: ``{"name": ..., "scene": SceneConfig JSON}`` (synthetic, SIMULATED inputs).
        out_root: output folder (one subfolder per video).
        store_url: artifact store; a re-run resumes from it and computes only what is missing.
        variant: method variant. method: parameter overrides (:func:`tasks.method.method_config`).
        runner: ``threads`` or ``dask`` (:func:`flows.runners.make_task_runner`). workers: parallel tasks.
    """
    rows = _dataset_run.with_options(task_runner=make_task_runner(runner, workers))(
        items, out_root, store_url, variant, method)
    root = Path(out_root)
    (root / "results.json").write_text(json.dumps(rows, indent=2, default=_json_default))
    header = ["video", *METRIC_ORDER]
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for row in rows:
        cells = [row["video"], *(_cell(row.get(k)) for k in METRIC_ORDER)]
        lines.append("| " + " | ".join(cells) + " |")
    (root / "results.md").write_text("\n".join(lines) + "\n")
    return rows


def _cell(value: Any) -> str:
    return "—" if value is None or (isinstance(value, float) and math.isnan(value)) else f"{value:.2f}"


def _json_default(value: Any) -> Any:
    return value.tolist() if hasattr(value, "tolist") else str(value)
