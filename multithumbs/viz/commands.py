"""Commands of the viz/export area: ``multithumbs export`` and ``multithumbs bench-plot``."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Optional

import typer

from multithumbs.errors import InputError


def _load_scene_points(path: Path, num_cuts: int) -> list:
    """Scene points from an ``.npz`` holding ``cut_0 .. cut_{C-1}`` arrays ``(N, 3)`` in the world frame."""
    import numpy as np

    if not path.is_file():
        raise InputError(f"{path}: no such file")
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {k: data[k] for k in data.files}
    except Exception as exc:  # numpy/zipfile raise many types for a broken file
        raise InputError(f"{path}: not a readable .npz file ({exc.__class__.__name__})") from None
    missing = [f"cut_{k}" for k in range(num_cuts) if f"cut_{k}" not in arrays]
    if missing:
        raise InputError(f"{path}: missing array {missing[0]!r} (one array cut_<k> of world points per cut)")
    return [arrays[f"cut_{k}"] for k in range(num_cuts)]


def register(app: typer.Typer) -> None:
    """Add the area's commands to the ``multithumbs`` app."""

    @app.command("export")
    def export_cmd(
        result: Path = typer.Argument(..., help="Result file (.npz); a ground-truth file is also a valid result."),
        video: Path = typer.Option(..., "--video", help="The input video the result was made from."),
        out: Path = typer.Option(..., "--out", help="Output folder (created if missing)."),
        truth: Optional[Path] = typer.Option(None, "--truth", help="Ground-truth file (.npz): truth panel, "
                                             "dashed truth trajectories and metrics."),
        metrics_path: Optional[Path] = typer.Option(None, "--metrics", help="Metrics JSON for the report "
                                                    "(default with --truth: computed)."),
        scene_points: Optional[Path] = typer.Option(None, "--scene-points", help=".npz with world-frame scene "
                                                    "points cut_0, cut_1, ... (N, 3) per cut."),
        skip: Optional[str] = typer.Option(None, "--skip", help="Comma-separated outputs to leave out: overlay, "
                                           "trajectory, smpl, cameras, colmap, bvh, glb, rrd, report."),
        glb_stride: int = typer.Option(1, "--glb-stride", help="Export every n-th frame to the GLB."),
        bvh_scale: float = typer.Option(1.0, "--bvh-scale", help="BVH length unit per metre (100 = centimetres)."),
        overwrite: bool = typer.Option(False, "--overwrite", help="Replace files in --out not written by an "
                                       "earlier export."),
        as_json: bool = typer.Option(False, "--json", help="Print the written files as JSON."),
        smpl_model: Optional[Path] = typer.Option(None, "--smpl-model", help="SMPL model file (.npz or .pkl); "
                                                  "default: $MULTITHUMBS_SMPL_MODEL, else the procedural body."),
    ) -> None:
        """Overlay video, top-down plot, SMPL/camera/COLMAP/BVH/GLB/rerun exports and a report of one result."""
        from rich.console import Console

        from multithumbs.body.model import load_body_model
        from multithumbs.io import load_ground_truth, load_result
        from multithumbs.viz.outputs import OUTPUT_KINDS, write_video_outputs

        console = Console(stderr=True)
        world = load_result(result)
        gt = load_ground_truth(truth)[0] if truth is not None else None
        if gt is not None and gt.world.num_frames != world.num_frames:
            raise InputError(f"{truth}: {gt.world.num_frames} frames, but {result} has {world.num_frames}")
        skipped = [s.strip() for s in skip.split(",") if s.strip()] if skip else []
        unknown = [s for s in skipped if s not in OUTPUT_KINDS]
        if unknown:
            raise InputError(f"--skip: unknown output {unknown[0]!r} (known: {', '.join(OUTPUT_KINDS)})")
        if glb_stride < 1:
            raise InputError(f"--glb-stride: must be at least 1, got {glb_stride}")
        if not bvh_scale > 0:
            raise InputError(f"--bvh-scale: must be positive, got {bvh_scale}")
        points = _load_scene_points(scene_points, int(world.cut_frames.size)) if scene_points else None
        body = load_body_model(smpl_model)
        metrics = None
        if metrics_path is not None:
            try:
                metrics = json.loads(metrics_path.read_text(encoding="utf-8"))
            except (OSError, ValueError) as exc:
                raise InputError(f"{metrics_path}: not a readable JSON file ({exc.__class__.__name__})") from None
        elif gt is not None:
            from multithumbs.metrics.evaluate import evaluate

            metrics = evaluate(world, gt, body)
        run_info = {"result": str(result), "body_model": body.source}
        with console.status("exporting") as status:
            written = write_video_outputs(out, world, video, gt, metrics, run_info, points, body,
                                          include=[k for k in OUTPUT_KINDS if k not in skipped], overwrite=overwrite,
                                          glb_stride=glb_stride, bvh_scale=bvh_scale,
                                          progress=lambda name: status.update(f"exporting: {name}"))
        if as_json:
            print(json.dumps({k: str(v) for k, v in written.items()}, indent=1))
            return
        for key, path in written.items():
            console.print(f"  {key:22s} {path}")

    @app.command("bench-plot")
    def bench_plot_cmd(
        summary: Path = typer.Argument(..., help="JSON printed by `multithumbs bench --json`."),
        out: Path = typer.Option(..., "--out", help="Output folder (created if missing)."),
        metrics: Optional[str] = typer.Option(None, "--metrics", help="Comma-separated metrics (default: all)."),
        overwrite: bool = typer.Option(False, "--overwrite", help="Replace existing plots."),
    ) -> None:
        """One bar chart per metric (PNG and SVG): every scene and variant of a benchmark run."""
        from rich.console import Console

        from multithumbs.viz.plots import benchmark_table, write_benchmark_plots

        try:
            data = json.loads(summary.read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:
            raise InputError(f"{summary}: not a readable JSON file ({exc.__class__.__name__})") from None
        _, known, _ = benchmark_table(data)
        wanted = [m.strip() for m in metrics.split(",") if m.strip()] if metrics else known
        for m in wanted:
            if m not in known:
                raise InputError(f"--metrics: {m!r} is not in {summary} ({', '.join(known)})")
        if out.exists() and not out.is_dir():
            raise InputError(f"{out}: exists and is not a folder")
        out.mkdir(parents=True, exist_ok=True)
        if not overwrite:
            for m in wanted:
                safe = "".join(ch if ch.isalnum() or ch in "-_" else "_" for ch in m)
                for fmt in ("png", "svg"):
                    if (out / f"bench_{safe}.{fmt}").exists():
                        raise InputError(f"{out / f'bench_{safe}.{fmt}'}: already exists (pass --overwrite to replace it)")
        written = write_benchmark_plots(out, data, wanted)
        for key, path in written.items():
            Console(stderr=True).print(f"  {key:22s} {path}")
