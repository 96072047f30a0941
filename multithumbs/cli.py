"""The ``multithumbs`` command line. Usage errors print one line and exit with code 2."""

from __future__ import annotations

import importlib
import json
import sys
from pathlib import Path
from typing import Optional

import typer
from rich.console import Console
from rich.table import Table

from multithumbs.cli_format import SMPL_OPTION, console, hide_flag_types, jsonable as _jsonable
from multithumbs.cli_runtime import finish, flow_environment, flow_logging, log_file, refuse, start_flow_api
from multithumbs.errors import InputError

app = typer.Typer(add_completion=False, no_args_is_help=True, pretty_exceptions_enable=False,
                  help="Multi-THuMBS: multi-person 3D human meshes across the cuts of edited video.")

hide_flag_types()


@app.command("eval")
def evaluate_cmd(
    result: Path = typer.Argument(..., help="Result file (.npz); a ground-truth file is also a valid result."),
    truth: Path = typer.Argument(..., help="Ground-truth file (.npz)."),
    as_json: bool = typer.Option(False, "--json", help="Print all metrics as JSON."),
    smpl_model: Optional[Path] = SMPL_OPTION,
) -> None:
    """Score a result against ground truth with every metric of docs/METRICS.md."""
    from multithumbs.body.model import load_body_model
    from multithumbs.io import load_ground_truth, load_result
    from multithumbs.metrics.evaluate import evaluate

    predicted = load_result(result)
    gt, _ = load_ground_truth(truth)
    if predicted.num_frames != gt.world.num_frames:
        raise InputError(f"{result}: {predicted.num_frames} frames, but the ground truth has {gt.world.num_frames}")
    metrics = evaluate(predicted, gt, load_body_model(smpl_model))
    if as_json:
        print(json.dumps(_jsonable(metrics), indent=2, sort_keys=True))
        return
    from multithumbs.metric_names import report_rows

    table = Table(title=f"{result.name} vs {truth.name}")
    table.add_column("metric")
    table.add_column("value", justify="right")
    table.add_column("unit")
    for row in report_rows(metrics):
        value = row["value"]
        table.add_row(row["metric"], f"{value:.3f}" if isinstance(value, (int, float)) else str(value), row["unit"])
    Console().print(table)


RUN_OUTPUTS = ("result.npz", "metrics.json", "overlay.mp4", "report.md", "outputs.json")


@app.command("run")
def run_cmd(
    video: Path = typer.Argument(..., help="The edited video."),
    out: Path = typer.Option(..., "--out", help="Output folder (created if missing)."),
    perception: str = typer.Option("blazepose", "--perception", help="Per-shot people: 'blazepose' (on CPU, from "
                                   "the pixels), 'phalp:RESULTS.pkl' (4DHumans/PHALP results), 'hmr2'; optionally "
                                   "'+vitpose' '+sam' refiners."),
    trust_pickle: bool = typer.Option(False, "--trust-pickle", help="Allow loading pickled results (pickles run "
                                      "code when loaded: only for files you trust)."),
    device: str = typer.Option("auto", "--device", help="Torch device of the learned perception backends (hmr2, "
                               "vitpose, sam): auto (CUDA when present), cpu, cuda, cuda:N."),
    intrinsics: Optional[str] = typer.Option(None, "--intrinsics", help="fx,fy,cx,cy of the camera in pixels "
                                             "(default: estimated from the pixels: a moving camera, people's "
                                             "heights, else a 60 degree horizontal field of view)."),
    truth: Optional[Path] = typer.Option(None, "--truth", help="Ground truth .npz to score against."),
    variant: str = typer.Option("full", "--variant", help="Method variant (an ablation or baseline)."),
    settings: list[str] = typer.Option([], "--set", help="Method parameter, e.g. --set reid.max_distance=0.8."),
    store: Optional[str] = typer.Option(None, "--store", help="Artifact store URL (default: OUT/store)."),
    overwrite: bool = typer.Option(False, "--overwrite", help="Reuse an output folder that holds results."),
    as_json: bool = typer.Option(False, "--json", help="Print the run's summary as JSON."),
    smpl_model: Optional[Path] = SMPL_OPTION,
) -> None:
    """Reconstruct the people of a video across its cuts through the Prefect flow (embedded API): shots,
    camera trajectories and shared spaces from the pixels, people from --perception."""
    flow_environment()  # before anything imports prefect: its settings are read at import
    from multithumbs.extras import require
    from multithumbs.io import check_output_dir, make_output_dir
    from multithumbs.perception import check_backends, parse_spec
    from multithumbs.video import check_intrinsics, probe_video

    # Every check a user can fail runs before Prefect (and torch) is imported, so mistakes cost a second,
    # not a minute; the method's parameters need torch's modules and come last.
    info = probe_video(video)
    terms = parse_spec(perception)
    for term in terms:
        if term.backend == "phalp":
            path = Path(term.argument)
            if not path.is_file():
                raise InputError(f"--perception {perception!r}: {path}: no such results file")
            if not trust_pickle:
                raise InputError(f"--perception {path}: a pickle runs code when loaded; pass --trust-pickle if you "
                                 f"trust this file")
    check_backends(terms)
    require("scenedetect", "multithumbs run (shot detection)")
    if smpl_model is not None and not smpl_model.is_file():
        raise InputError(f"--smpl-model {smpl_model}: no such file")
    K = None
    if intrinsics is not None:
        try:
            K = check_intrinsics(intrinsics.split(","))
        except ValueError:  # InputError is one too
            raise InputError(f"--intrinsics {intrinsics!r}: expected four numbers fx,fy,cx,cy, fx and fy "
                             f"positive") from None
    if truth is not None and not truth.is_file():
        raise InputError(f"--truth {truth}: no such file")
    check_output_dir(out, overwrite, RUN_OUTPUTS)
    from multithumbs.overrides import method_config, parse_assignments

    method = parse_assignments(settings)
    start_flow_api()
    method_config(variant, method)
    if terms[0].backend == "hmr2" or len(terms) > 1:
        from multithumbs.perception.hmr2 import select_device

        select_device(device)  # --device cuda on a machine without CUDA fails here, in one line
    from multithumbs.body.paths import resolve_model_path

    resolve_model_path(smpl_model)
    out_dir = make_output_dir(out)
    from flows.video import reconstruct_video
    from multithumbs.metric_names import METRIC_KEYS

    flow_logging()
    from multithumbs.cli_format import stage_bars

    with stage_bars(f"reconstructing {video.name}: {info.num_frames} frames, {info.width}x{info.height}"):
        summary = reconstruct_video(str(video.resolve()), str(out_dir.resolve()),
                                    store or str((out_dir / "store").resolve()), perception, trust_pickle, K,
                                    variant, method, None if truth is None else str(truth.resolve()),
                                    smpl_model=None if smpl_model is None else str(smpl_model.resolve()),
                                    device=device)
    if as_json:
        print(json.dumps(_jsonable(summary), indent=2, sort_keys=True))
        return
    from multithumbs.cli_format import file_lines, format_value, output_console
    from multithumbs.metric_names import METRIC_UNITS

    table = Table(title=f"{video.name}: {summary['num_shots']} shots ({variant})")
    table.add_column("stage", no_wrap=True)
    table.add_column("backend or value", overflow="fold")
    table.add_column("unit", overflow="fold")
    for stage, backend in summary["backends"].items():
        table.add_row(stage, backend, "")
    for stage, seconds in summary["timings"].items():
        table.add_row(stage, f"{seconds:.1f}", "s")
    for key, value in (summary["metrics"] or {}).items():
        if key in METRIC_KEYS:
            table.add_row(key, format_value(value, ".3f"), METRIC_UNITS.get(key, ""))
    output_console().print(table)
    console.print(summary["backends"].get("focal length", ""), highlight=False)
    people = summary.get("people", [])
    if people:
        console.print("people (global id: shots): " + "; ".join(
            f"{p['id']}: {', '.join(map(str, p['shots']))}" for p in people), highlight=False, soft_wrap=True)
    else:
        console.print(f"no people found in any of the {summary['num_shots']} shots of {video.name} (perception: "
                      f"{summary['backends'].get('perception', perception)}); the result holds the cameras only",
                      highlight=False)
    # Paths relative to the output folder, subfolders kept (smpl/..., bvh/...): what a user opens next.
    console.print(f"outputs in {out_dir}:")
    for line in file_lines(summary["files"], out_dir):
        console.print(line, highlight=False, soft_wrap=True)


@app.command("demo")
def demo_cmd(
    out: Path = typer.Option(Path("demo"), "--out", help="Output folder."),
    scene: str = typer.Option("s09_crossing_at_cut", "--scene", help="Scene of the standard suite."),
    variant: str = typer.Option("full", "--variant", help="Method variant."),
    store: Optional[str] = typer.Option(None, "--store", help="Artifact store URL (default: OUT/store)."),
    overwrite: bool = typer.Option(False, "--overwrite", help="Reuse an output folder that holds a demo."),
    smpl_model: Optional[Path] = SMPL_OPTION,
) -> None:
    """Synthesise a standard-suite scene and reconstruct it through the real Prefect flow (embedded API)."""
    flow_environment()
    from multithumbs.io import check_output_dir

    check_output_dir(out, overwrite, ("video.mp4", "ground_truth.npz", "contact_sheet.png"))
    start_flow_api()
    from multithumbs.metric_names import METRIC_KEYS
    from multithumbs.method.config import variant_config
    from multithumbs.synth.files import prepare_output_dir
    from multithumbs.synth.config import config_to_json
    from multithumbs.synth.suite import suite_scene

    config = suite_scene("standard", scene)
    variant_config(variant)
    from multithumbs.body.paths import resolve_model_path

    resolve_model_path(smpl_model)  # a missing file fails before Prefect starts
    out_dir = prepare_output_dir(out, overwrite)
    from flows.reconstruct import reconstruct_synthetic

    flow_logging()

    # True of both cases without asking the store first (it may be remote): a re-run computes nothing,
    # but still starts the embedded Prefect API.
    with console.status(f"{scene}: synthesising and reconstructing (about a minute the first time; "
                        f"a re-run reuses the store)"):
        metrics = reconstruct_synthetic(config_to_json(config), str(out_dir.resolve()),
                                        store or str((out_dir / "store").resolve()), variant,
                                        smpl_model=None if smpl_model is None else str(smpl_model.resolve()))
    from multithumbs.cli_format import metric_list_table, output_console
    from multithumbs.metric_names import METRIC_UNITS

    # The title stays one line; the label a reader must not miss goes under the table at full width (a
    # caption would wrap to the table's narrow width).
    out = output_console()
    out.print(metric_list_table(f"{scene} ({variant})", metrics, METRIC_KEYS, METRIC_UNITS))
    out.print("SIMULATED: perception, shared space and camera tracking; the method is real.")
    console.print(f"outputs in {out_dir}: video.mp4, ground_truth.npz, result.npz, metrics.json, overlay.mp4, "
                  f"trajectory.png, report.md, scene.glb, scene.rrd, smpl/, bvh/, colmap/ (list: outputs.json)")


@app.command("dashboard")
def dashboard_cmd(
    port: int = typer.Option(4200, "--port", help="Port of the UI and API."),
    host: str = typer.Option("127.0.0.1", "--host", help="Address to listen on."),
) -> None:
    """Prefect's dashboard on the CLI's Prefect home (MULTITHUMBS_CACHE/prefect): the runs of `run` and `demo`
    so far, and, while it runs, theirs go to it live (no server to start for each)."""
    import os

    flow_environment()
    from flows.local_api import serve_dashboard

    try:
        code = serve_dashboard(Path(os.environ["PREFECT_HOME"]), host, port, console.print)
    except RuntimeError as exc:
        raise InputError(f"dashboard: {exc}") from None
    if code not in (0, None, -2, 130):
        raise InputError(f"dashboard: the Prefect server exited with code {code}")


def _register(module: str) -> None:
    """Add the commands an area defines beside its code (``register(app)``); imports stay lazy inside them."""
    importlib.import_module(module).register(app)


# Commands of the library's areas: one line per area, sorted.
_register("multithumbs.datasets.commands")
_register("multithumbs.scene.commands")
_register("multithumbs.synth.commands")
_register("multithumbs.viz.commands")
# end of area commands


def _dispatch() -> None:
    """Run the app; user errors become one line on stderr and exit code 2."""
    try:
        app(standalone_mode=False)
    except InputError as exc:
        refuse(str(exc), exc)
    except ModuleNotFoundError as exc:
        # A package only scripts/setup.sh installs, missing where no command checked for it.
        from multithumbs.extras import missing_package_message

        message = missing_package_message(exc.name or "")
        if message is None:
            raise
        refuse(message, exc)
    except SystemExit:
        raise
    except Exception as exc:
        # Usage errors of typer's parser: typer vendors click, so match their shape, not a class.
        if hasattr(exc, "format_message") and isinstance(getattr(exc, "exit_code", None), int):
            print(f"error: {exc.format_message()}", file=sys.stderr)
            sys.exit(2)
        if type(exc).__name__ == "Abort":
            sys.exit(130)
        print(f"log of this run: {log_file()}", file=sys.stderr)
        raise


def main() -> None:
    """Entry point (:func:`_dispatch`); :func:`multithumbs.cli_runtime.finish` ends the process."""
    code: int | str | None = 1
    try:
        _dispatch()
        code = 0
    except SystemExit as exc:
        code = exc.code
    except KeyboardInterrupt:
        code = 130
    except BaseException:
        import traceback

        traceback.print_exc()
    finish(code)


if __name__ == "__main__":
    main()
