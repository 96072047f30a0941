"""Commands of the synthetic world: ``multithumbs synth``, ``multithumbs suite`` and ``multithumbs bench``."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Optional

import typer
from rich import box
from rich.table import Table

from multithumbs.cli_format import SMPL_OPTION, console, jsonable as _jsonable, progress as _progress
from multithumbs.errors import InputError


def register(app: typer.Typer) -> None:
    """Add the area's commands to the ``multithumbs`` app."""

    @app.command()
    def synth(
        out: Path = typer.Option(..., "--out", help="Output folder (created if missing)."),
        people: int = typer.Option(3, "--people", help="Number of people."),
        shots: int = typer.Option(2, "--shots", help="Number of shots (one camera each)."),
        frames: int = typer.Option(120, "--frames", help="Number of frames."),
        seed: int = typer.Option(0, "--seed", help="Seed of every random choice."),
        cut_angle: float = typer.Option(45.0, "--cut-angle", help="Yaw between consecutive shots' cameras (degrees)."),
        moving: bool = typer.Option(False, "--moving", help="Cameras dolly sideways during their shots."),
        width: int = typer.Option(640, "--width", help="Image width (pixels)."),
        height: int = typer.Option(360, "--height", help="Image height (pixels)."),
        fps: float = typer.Option(30.0, "--fps", help="Frames per second."),
        suite_name: Optional[str] = typer.Option(None, "--suite", help="Take the scene from this named suite."),
        scene_name: Optional[str] = typer.Option(None, "--scene", help="Scene name within --suite."),
        overwrite: bool = typer.Option(False, "--overwrite", help="Replace existing outputs in --out."),
        smpl_model: Optional[Path] = SMPL_OPTION,
    ) -> None:
        """Synthesise a multi-shot scene: video.mp4, ground_truth.npz, contact_sheet.png and perception.pkl
        (SIMULATED per-shot perception in 4DHumans/PHALP's results format, for ``multithumbs run``)."""
        from multithumbs.body.model import load_body_model
        from multithumbs.synth.files import prepare_output_dir, write_synthetic
        from multithumbs.synth.scene import SceneConfig, synthesize
        from multithumbs.synth.suite import suite_scene

        if suite_name or scene_name:
            if not (suite_name and scene_name):
                raise InputError("--suite and --scene go together")
            config = suite_scene(suite_name, scene_name)
        else:
            config = SceneConfig(num_people=people, num_shots=shots, num_frames=frames, seed=seed,
                                 cut_angle_deg=cut_angle, moving_cameras=moving, image_size=(height, width), fps=fps)
        out_dir = prepare_output_dir(out, overwrite)
        body = load_body_model(smpl_model)
        with _progress() as bar:
            task = bar.add_task("rendering", total=config.num_frames)
            video = synthesize(config, body, progress=lambda done, total: bar.update(task, completed=done))
        paths = write_synthetic(out_dir, video)
        truth = video.truth
        from multithumbs.perception.phalp_export import export_phalp
        from multithumbs.synth.perception import simulate_perception

        # SIMULATED perception in 4DHumans/PHALP's format: `multithumbs run video.mp4 --perception phalp:...`.
        simulated = simulate_perception(video, body)
        paths["perception"] = export_phalp(out_dir / "perception.pkl", simulated, truth.world.shots(), body,
                                           overwrite=True)
        console.print(f"[bold]{config.name or 'scene'}[/]: {config.num_people} people, {config.num_shots} shots, "
                      f"{config.num_frames} frames, cuts at {truth.world.cut_frames.tolist()}, "
                      f"{int(truth.visible.sum())} visible person-frames")
        for kind, path in paths.items():
            console.print(f"  {kind:14s} {path}")


    @app.command("suite")
    def list_suite(name: str = typer.Argument("standard", help="Suite name."),
                   as_json: bool = typer.Option(False, "--json", help="Print JSON.")) -> None:
        """List the scenes of a named synthetic suite."""
        from dataclasses import asdict

        from multithumbs.synth.suite import suite

        configs = suite(name)
        if as_json:
            print(json.dumps([asdict(c) for c in configs], indent=2, default=str))
            return
        from multithumbs.cli_format import output_console, yes_no

        # The scene column never wraps: its names are what --scene takes. Free text (special) folds instead.
        # The scene column never wraps: its names are what --scene takes. Free text (special) folds instead;
        # whether cameras move is one of the specials, so that the narrowest terminal keeps room for them.
        table = Table(title=f"suite {name}", box=box.SIMPLE_HEAD, padding=(0, 1, 0, 0), caption="`synth --suite "
                      f"{name} --scene SCENE` renders one, `bench --scenes A,B` runs some", caption_justify="left")
        table.add_column("scene", no_wrap=True)
        for col in ("people", "shots", "frames"):
            table.add_column(col, justify="right", no_wrap=True)
        table.add_column("cut\nangle", justify="right", no_wrap=True)
        table.add_column("special", overflow="fold")
        for c in configs:
            moving = c.moving_cameras
            moving_text = (moving and "moving cameras" if not isinstance(moving, (list, tuple)) else
                           any(moving) and f"moving cameras: {yes_no(moving)}")
            special = ", ".join(filter(None, [moving_text, c.only_in_one_shot and "one-shot person",
                                              c.dressed_alike and "dressed alike", c.abreast_pair and "walking abreast",
                                              c.crossing_pair and "crossing"]))
            table.add_row(c.name, str(c.num_people), str(c.num_shots), str(c.num_frames), f"{c.cut_angle_deg:g}°",
                          special)
        output_console().print(table)

    @app.command("bench")
    def bench_cmd(
        suite_name: str = typer.Option("standard", "--suite", help="Named synthetic suite."),
        variants: Optional[str] = typer.Option(None, "--variants", help="Comma-separated variants (default: all)."),
        scenes: Optional[str] = typer.Option(None, "--scenes", help="Comma-separated scene names (default: all)."),
        workers: Optional[int] = typer.Option(None, "--workers", help="Worker processes (default: one per core)."),
        as_json: bool = typer.Option(False, "--json", help="Print JSON keyed by variant, then metric."),
        perception_file: str = typer.Option("direct", "--perception-file",
                                            help="direct, or phalp: the simulated perception through a "
                                                 "4DHumans/PHALP results file, as a real user's."),
        from_pixels: bool = typer.Option(False, "--from-pixels",
                                         help="Nothing simulated: cuts, people, cameras and shared spaces "
                                              "from the rendered video; the simulated run is shown beside it."),
        withhold_focal: bool = typer.Option(False, "--withhold-focal",
                                            help="With --from-pixels: withhold the true focal length and "
                                                 "estimate it from the pixels, as 'multithumbs run' does."),
        pixel_stages: Optional[str] = typer.Option(None, "--pixel-stages",
                                                   help="With --from-pixels: only these stages from the pixels, "
                                                        "the others simulated (comma-separated of shots, "
                                                        "perception, camera_tracking, shared_space; default all)."),
    ) -> None:
        """Run a synthetic suite with the full method, each ablation and each baseline; print the metrics."""
        import time

        from multithumbs.bench import BACKENDS, METRIC_KEYS, check_variants, checked_pixel_stages, run_suite, summarize
        from multithumbs.pipeline import VARIANTS
        from multithumbs.synth.suite import suite, suite_scene

        names = check_variants(variants.split(",")) if variants else list(VARIANTS)
        configs = [suite_scene(suite_name, n) for n in scenes.split(",")] if scenes else list(suite(suite_name))
        if workers is not None and workers < 1:
            raise InputError(f"--workers: need at least 1, got {workers}")
        if from_pixels and perception_file != "direct":
            raise InputError("--from-pixels: the people come from the pixels; --perception-file applies to "
                             "simulated perception only")
        if withhold_focal and not from_pixels:
            raise InputError("--withhold-focal: only with --from-pixels (simulated inputs use the true cameras)")
        if pixel_stages is not None and not from_pixels:
            raise InputError("--pixel-stages: only with --from-pixels")
        stages = checked_pixel_stages(pixel_stages)
        inputs = ("pixels_no_focal" if withhold_focal else "pixels") if from_pixels else "simulated"
        start = time.perf_counter()
        with _progress() as bar:
            task = bar.add_task(f"suite {suite_name}" + (" from pixels" if from_pixels else ""), total=len(configs))
            results = run_suite(configs, names, workers, progress=lambda s, done, total: bar.update(task, completed=done),
                                perception=perception_file, inputs=inputs, pixel_stages=stages,
                                input_cache=pixel_input_cache() if from_pixels else None)
        summary = summarize(results, names)
        elapsed = time.perf_counter() - start
        if from_pixels:
            with _progress() as bar:
                task = bar.add_task(f"suite {suite_name} simulated, for comparison", total=len(configs))
                simulated = run_suite(configs, names, workers,
                                      progress=lambda s, done, total: bar.update(task, completed=done))
            _print_pixels_bench(suite_name, configs, names, results, summary, summarize(simulated, names), elapsed,
                                as_json)
            return
        backends = dict(BACKENDS)
        if perception_file == "phalp":
            backends["perception"] = "simulated, through a 4DHumans/PHALP results file"
        if as_json:
            print(json.dumps(_jsonable({**summary, "_meta": {"suite": suite_name, "scenes": [c.name for c in configs],
                                                              "seconds": elapsed, "backends": backends,
                                                              **_machine()}}),
                             indent=1, sort_keys=True))
            return
        from multithumbs.cli_format import output_console, split_metric_tables
        from multithumbs.metrics.evaluate import METRIC_UNITS

        # Eleven metrics do not fit 80 columns beside the variant names: split_metric_tables packs them into
        # as many tables as the terminal needs, each repeating the variant column.
        out = output_console()
        means = {v: {k: summary[v][k]["mean"] for k in METRIC_KEYS} for v in names}
        tables = split_metric_tables(out, f"suite {suite_name}: {len(configs)} scenes, {elapsed:.0f} s, means",
                                     "variant", means, METRIC_KEYS, METRIC_UNITS,
                                     caption="backends: " + "; ".join(f"{k} {v}" for k, v in backends.items()))
        for table in tables:
            out.print(table)


def _machine() -> dict[str, str]:
    """The CPU a bench ran on and the kernels it used (figures move with unpinned kernels: cpu_kernels)."""
    from multithumbs.cpu_kernels import cpu_model, kernel_tag

    return {"cpu": cpu_model(), "kernels": kernel_tag()}


def pixel_input_cache():
    """The artifact store under the project's cache that keeps ``bench --from-pixels`` inputs between runs
    (``MULTITHUMBS_CACHE/bench_store``; ``tasks.bench_inputs``)."""
    from multithumbs.cli_runtime import cache_dir
    from tasks.bench_inputs import StoreInputCache

    return StoreInputCache(str(cache_dir() / "bench_store"))


def _print_pixels_bench(suite_name, configs, names, results, summary, simulated, elapsed, as_json) -> None:
    """``bench --from-pixels``: the nothing-simulated figures, scene by scene beside the simulated ones, and
    which backend produced each input stage of each scene, with its seconds."""
    from multithumbs.bench import METRIC_KEYS, PIXEL_STAGES
    from multithumbs.cli_format import output_console, split_metric_tables
    from multithumbs.metrics.evaluate import METRIC_UNITS

    # What made each stage over the suite (a stage's source may differ by scene: fallbacks).
    backends = {k: " | ".join(sorted({r.backends[k] for r in results if k in r.backends})) for k in PIXEL_STAGES}
    meta = {"suite": suite_name, "scenes": [c.name for c in configs], "seconds": elapsed,
            "backends": backends, "backends_per_scene": {r.scene: r.backends for r in results},
            "stage_seconds": {r.scene: r.stage_seconds for r in results}, **_machine()}
    if as_json:
        print(json.dumps(_jsonable({"pixels": summary, "simulated": simulated, "_meta": meta}), indent=1,
                         sort_keys=True))
        return
    out = output_console()
    means = {v: {k: summary[v][k]["mean"] for k in METRIC_KEYS} for v in names}
    for table in split_metric_tables(out, f"suite {suite_name} from pixels: {len(configs)} scenes, {elapsed:.0f} s, "
                                     f"means", "variant", means, METRIC_KEYS, METRIC_UNITS,
                                     caption="backends: " + "; ".join(f"{k} {v}" for k, v in backends.items())):
        out.print(table)
    shown = [v for v in ("full", "no_align", "independent_shots") if v in names] or list(names)[:1]
    table = Table(title="W-MPJPE (mm) and IDs per scene: pixels / simulated", box=box.SIMPLE_HEAD)
    table.add_column("scene", no_wrap=True)
    for v in shown:
        table.add_column(v, justify="right")
    for r in results:
        table.add_row(r.scene, *(f"{summary[v]['w_mpjpe']['per_scene'][r.scene]:.0f}/"
                                 f"{simulated[v]['w_mpjpe']['per_scene'][r.scene]:.0f} "
                                 f"{summary[v]['ids']['per_scene'][r.scene]:.0f}/"
                                 f"{simulated[v]['ids']['per_scene'][r.scene]:.0f}" for v in shown))
    out.print(table)
    stages = sorted({k for r in results for k in r.stage_seconds})
    totals = {k: sum(r.stage_seconds.get(k, 0.0) for r in results) for k in stages}
    for r in results:
        if "focal" in r.backends:
            out.print(f"{r.scene}: {r.backends['focal']}", highlight=False, soft_wrap=True)
    kept = sum("inputs" in r.backends for r in results)
    out.print("input stages, seconds over the suite: " + ", ".join(f"{k} {v:.0f}" for k, v in totals.items())
              + (f" (as first computed: {kept} of {len(results)} scenes' inputs kept from an earlier run)"
                 if kept else ""), highlight=False, soft_wrap=True)
