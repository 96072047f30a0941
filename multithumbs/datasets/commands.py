"""CLI of the datasets area: ``multithumbs dataset list|build`` and ``multithumbs smpl-convert``."""

from __future__ import annotations

import json
from pathlib import Path
from typing import List, Optional

import typer
from rich.console import Console
from rich.table import Table

console = Console(stderr=True)


def register(app: typer.Typer) -> None:
    """Add the ``dataset`` sub-app and the ``smpl-convert`` command to ``app``."""
    dataset_app = typer.Typer(no_args_is_help=True, help="Real datasets: list what a data root holds, build "
                              "benchmark clips from spec files.")

    @dataset_app.command("list")
    def list_cmd(
        data_root: Path = typer.Argument(..., help="Root folder of EgoHumans, Harmony4D, EgoBody, AVA or sitcoms."),
        dataset: Optional[str] = typer.Option(None, "--dataset", help="Dataset (default: recognised from the layout)."),
        as_json: bool = typer.Option(False, "--json", help="Print JSON."),
    ) -> None:
        """What a data root holds: dataset, sequences, cameras, people, frames (or edited clips)."""
        from multithumbs.datasets.catalog import describe_root

        info = describe_root(data_root, dataset)
        if as_json:
            print(json.dumps(info, indent=2, sort_keys=True))
            return
        out = Console()
        if "sequences" in info:
            table = Table(title=f"{info['dataset']} at {info['root']}")
            for col in ("sequence", "frames", "fps", "cameras", "people", "alignment"):
                table.add_column(col, overflow="fold")
            for seq in info["sequences"]:
                table.add_row(seq["sequence"], str(seq["num_frames"]), f"{seq['fps']:g}",
                              ", ".join(c["name"] for c in seq["cameras"]), ", ".join(seq["people"]), seq["alignment"])
            out.print(table)
            for seq in info["sequences"]:
                for note in seq["notes"]:
                    out.print(f"  {seq['sequence']}: {note}")
        elif info["dataset"] == "ava":
            for ann in info["annotations"]:
                out.print(f"{ann['file']}: {ann['rows']} boxes, {ann['videos']} videos, {ann['seconds']} seconds")
            for folder, counts in info["frames"].items():
                out.print(f"{folder}: {counts['videos']} videos, {counts['images']} images")
            for clip in info["clips"]:
                out.print(f"clip {clip['name']}: {clip['frames']} frames, cuts {clip['cuts']}, "
                          f"{clip['frames_present']} frames present")
        else:
            table = Table(title=f"sitcoms at {info['root']}")
            for col in ("location", "images", "humans", "cross-shot pairs", "frames present", "cameras"):
                table.add_column(col, overflow="fold")
            for loc in info["locations"]:
                table.add_row(loc["location"], str(loc["images"]), str(loc["humans"]), str(loc["pairs"]),
                              str(loc["frames_present"]), str(loc["cameras"]))
            out.print(table)

    @dataset_app.command("build")
    def build_cmd(
        specs: List[Path] = typer.Argument(..., help="Spec files (.json or .toml; a .json may hold a list of specs)."),
        data_root: Path = typer.Option(..., "--data-root", help="The dataset's root folder."),
        out: Path = typer.Option(..., "--out", help="Folder receiving one clip folder per spec."),
        smpl_dir: Optional[Path] = typer.Option(None, "--smpl-dir", help="Folder of SMPL_{MALE,FEMALE}.npz "
                                                "(EgoBody's gendered ground truth)."),
        overwrite: bool = typer.Option(False, "--overwrite", help="Replace clip folders holding another clip."),
        as_json: bool = typer.Option(False, "--json", help="Print {name: clip folder} as JSON."),
    ) -> None:
        """Build benchmark clips (video.mp4, ground_truth.npz, spec.json) from spec files."""
        from multithumbs.datasets.benchmark import iter_benchmark
        from multithumbs.datasets.clip_specs import load_specs

        loaded = load_specs(specs)
        built = {}
        for name, clip_dir in iter_benchmark(loaded, data_root, out, smpl_dir=smpl_dir, overwrite=overwrite):
            built[name] = str(clip_dir)
            if not as_json:
                console.print(f"[bold]{name}[/]: {clip_dir}")
        if as_json:
            print(json.dumps(built, indent=2))

    @dataset_app.command("run")
    def run_cmd(
        specs: List[Path] = typer.Argument(..., help="Spec files of the benchmark's clips."),
        data_root: Path = typer.Option(..., "--data-root", help="The dataset's root folder."),
        out: Path = typer.Option(..., "--out", help="Folder for the clips (OUT/clips), every clip's outputs "
                                 "(OUT/runs/NAME) and the results table (OUT/runs/results.md, .json)."),
        perception: str = typer.Option("oracle", "--perception", help="'oracle' (exact tracks from each clip's "
                                       "ground truth: measures everything after perception) or a folder of "
                                       "4DHumans/PHALP results NAME.pkl."),
        trust_pickle: bool = typer.Option(False, "--trust-pickle", help="Allow loading the PHALP pickles."),
        smpl_dir: Optional[Path] = typer.Option(None, "--smpl-dir", help="Folder of the user's SMPL models."),
        variant: str = typer.Option("full", "--variant", help="Method variant."),
        store: Optional[str] = typer.Option(None, "--store", help="Artifact store URL (default: OUT/store)."),
        as_json: bool = typer.Option(False, "--json", help="Print the results table as JSON."),
    ) -> None:
        """Build the benchmark's clips and run the dataset flow over them (resumable; for a schedule, deploy
        flows/dataset.py:reconstruct_dataset, see deploy/README.md)."""
        from multithumbs.cli_runtime import flow_environment, flow_logging, start_flow_api
        from multithumbs.errors import InputError

        flow_environment()
        if perception != "oracle" and not Path(perception).is_dir():
            raise InputError(f"--perception {perception}: neither 'oracle' nor a folder of PHALP results")
        start_flow_api()
        from flows.dataset import benchmark_items, reconstruct_dataset

        flow_logging()
        items = benchmark_items([str(s) for s in specs], str(data_root), str(out / "clips"), perception,
                                trust_pickle, None if smpl_dir is None else str(smpl_dir))
        with console.status(f"{len(items)} clips through the dataset flow"):
            rows = reconstruct_dataset(items, str((out / "runs").resolve()),
                                       store or str((out / "store").resolve()), variant)
        if as_json:
            print(json.dumps(rows, indent=2, default=str))
            return
        console.print((out / "runs" / "results.md").read_text())

    app.add_typer(dataset_app, name="dataset")

    @app.command("smpl-convert")
    def smpl_convert_cmd(
        source: Path = typer.Argument(..., help="SMPL model .pkl (the official files hold chumpy objects)."),
        destination: Path = typer.Argument(..., help="The .npz to write."),
        overwrite: bool = typer.Option(False, "--overwrite", help="Replace an existing destination."),
        as_json: bool = typer.Option(False, "--json", help="Print the verification as JSON."),
    ) -> None:
        """Convert a user's SMPL .pkl to plain numpy once, verified by a forward pass of both models."""
        from multithumbs.datasets.smpl_files import convert_and_verify

        check = convert_and_verify(source, destination, overwrite=overwrite)
        summary = {"destination": str(check.destination), "vertices": check.num_vertices, "poses": check.num_poses,
                   "max_vertex_difference_m": check.max_vertex_difference,
                   "max_joint_difference_m": check.max_joint_difference}
        if as_json:
            print(json.dumps(summary, indent=2))
            return
        console.print(f"wrote {check.destination}: {check.num_vertices} vertices; verified on {check.num_poses} "
                      f"random bodies, largest vertex difference {check.max_vertex_difference:.2e} m")
