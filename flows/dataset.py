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
from flows.video import reconstruct_video
from tasks.evaluation import evaluate_result
from tasks.inputs import simulate_inputs
from tasks.outputs import write_outputs
from tasks.method import method_params


def _item_name(item: dict[str, Any], index: int) -> str:
    if item.get("name"):
        return str(item["name"])
    if "video" in item:
        return Path(item["video"]).parent.name or f"video{index:03d}"
    return str(item.get("scene", {}).get("name") or f"video{index:03d}")


def _check_items(items: list[dict[str, Any]]) -> list[str]:
    from multithumbs.errors import InputError

    if not items:
        raise InputError("dataset: no videos given")
    names = []
    for i, item in enumerate(items):
        if ("scene" in item) == ("video" in item):
            raise InputError(f"dataset item {i}: needs either a 'scene' (a synthetic SceneConfig as JSON) or a "
                             f"'video' (with 'perception')")
        if "video" in item and not item.get("perception"):
            raise InputError(f"dataset item {i} ({item['video']}): needs a 'perception' spec")
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
    rows = {}
    videos = [(name, item) for name, item in zip(names, items) if "video" in item]
    for done, (name, item) in enumerate(videos, 1):  # real videos: each its own flow run (parallel inside)
        summary = reconstruct_video(item["video"], str(root / name), store_url, item["perception"],
                                    item.get("trust_pickle", False), item.get("intrinsics"), variant, method,
                                    item.get("truth"), cuts=item.get("cuts"))
        rows[name] = {"video": name, **{k: (summary["metrics"] or {}).get(k) for k in METRIC_ORDER},
                      "backends": summary["backends"]}
        update_progress_artifact(progress, 50.0 * done / len(items))
    scenes = [(name, item) for name, item in zip(names, items) if "scene" in item]
    if scenes:
        rows.update(_synthetic_rows(scenes, root, store_url, variant, method, progress))
    table = [rows[name] for name in names]
    create_table_artifact(key="dataset-results", table=table, description=f"{len(table)} videos ({variant})")
    return table


def _synthetic_rows(scenes: list[tuple[str, dict[str, Any]]], root: Path, store_url: str, variant: str,
                    method: dict[str, Any] | None, progress) -> dict[str, dict[str, Any]]:
    """Synthetic items (SIMULATED inputs): every stage as tasks in parallel across videos; rows by name."""
    names = [name for name, _ in scenes]
    input_futures = []
    for name, item in scenes:
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
    rows = {}
    for name, out, m, future in zip(names, outs, metrics, output_futures):
        publish_report(name, variant, future.result(), m)
        rows[name] = {"video": name, **{k: m.get(k) for k in METRIC_ORDER}, "result": out["result"].key}
    update_progress_artifact(progress, 100.0)
    return rows


@flow(name="reconstruct-dataset")
def reconstruct_dataset(items: list[dict[str, Any]], out_root: str, store_url: str, variant: str = "full",
                        method: dict[str, Any] | None = None, runner: str = "threads", workers: int = 2
                        ) -> list[dict[str, Any]]:
    """Reconstruct and score many videos; write each one's outputs to ``out_root/NAME`` and the table to
    ``out_root/results.json`` and ``results.md``.

    Args:
        items: one dict per video: ``{"name": ..., "scene": SceneConfig JSON}`` (synthetic, SIMULATED inputs) or
            ``{"name": ..., "video": PATH, "perception": SPEC, "trust_pickle": bool, "truth": GT.npz,
            "intrinsics": [fx, fy, cx, cy], "cuts": [...]}`` (a real video through
            :func:`flows.video.reconstruct_video`; ``cuts`` when known, e.g. a benchmark clip).
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
    if isinstance(value, (list, tuple)):
        return "; ".join(_cell(v) for v in value)
    if isinstance(value, str):
        return value
    return "—" if value is None or (isinstance(value, float) and math.isnan(value)) else f"{value:.2f}"


def _json_default(value: Any) -> Any:
    return value.tolist() if hasattr(value, "tolist") else str(value)


def benchmark_items(specs: list[str], data_root: str, clips_dir: str, perception: str = "oracle",
                    trust_pickle: bool = False, smpl_dir: str | None = None) -> list[dict[str, Any]]:
    """Build (or reuse) a real-data benchmark's clips and describe them as dataset items.

    Args:
        specs: clip spec files (:mod:`multithumbs.datasets.clip_specs`).
        data_root: the dataset's root. clips_dir: where clips are built.
        perception: ``oracle`` (exact tracks from each clip's ground truth: measures everything after
            perception, labelled so) or a folder holding 4DHumans/PHALP results ``NAME.pkl`` per clip.
        trust_pickle: allow loading those results. smpl_dir: the user's SMPL models (EgoBody).
    The cut frames come from the specs (the benchmark defines them); the intrinsics are the first frame's.
    """
    from multithumbs.datasets.benchmark import iter_benchmark
    from multithumbs.errors import InputError
    from multithumbs.io import load_ground_truth

    items = []
    for name, clip in iter_benchmark(specs, data_root, clips_dir, smpl_dir):
        truth = load_ground_truth(clip / "ground_truth.npz")[0]
        if perception == "oracle":
            spec = f"oracle:{clip / 'ground_truth.npz'}"
        else:
            results = Path(perception) / f"{name}.pkl"
            if not results.is_file():
                raise InputError(f"perception {perception}: no results {results.name} for clip {name}")
            spec = f"phalp:{results}"
        K = truth.world.K[0]
        items.append({"name": name, "video": str(clip / "video.mp4"), "perception": spec,
                      "trust_pickle": trust_pickle, "truth": str(clip / "ground_truth.npz"),
                      "intrinsics": [float(K[0, 0]), float(K[1, 1]), float(K[0, 2]), float(K[1, 2])],
                      "cuts": truth.world.cut_frames.tolist()})
    return items


@flow(name="dataset-benchmark")
def dataset_benchmark(specs: list[str], data_root: str, out_dir: str, perception: str = "oracle",
                      trust_pickle: bool = False, smpl_dir: str | None = None, store_url: str | None = None,
                      variant: str = "full", runner: str = "threads", workers: int = 2) -> list[dict[str, Any]]:
    """A real-data benchmark on a schedule: build (or reuse) the clips of ``specs`` from ``data_root`` into
    ``out_dir/clips`` and run :func:`reconstruct_dataset` over them into ``out_dir/runs`` (results table
    ``results.md``). Arguments as :func:`benchmark_items` and :func:`reconstruct_dataset`; the store defaults
    to ``out_dir/store``, so each scheduled run resumes and recomputes only what changed.
    """
    root = Path(out_dir)
    items = benchmark_items(specs, data_root, str(root / "clips"), perception, trust_pickle, smpl_dir)
    return reconstruct_dataset(items, str(root / "runs"), store_url or str(root / "store"), variant,
                               runner=runner, workers=workers)
