"""The nothing-simulated suite again with other labelling or method settings, in minutes instead of a bench.

``multithumbs bench --from-pixels`` keeps each scene's pixel inputs in the store under ``MULTITHUMBS_CACHE``.
This script reads them and runs the method on them with the stored cuts, cameras and shared spaces, under
the method settings given (``--method section.name=value,...``: fields of the
:class:`multithumbs.method.config.MethodConfig` sections ``align``, ``reid`` and ``post``), about 40 s a
scene. With ``--facing``, it first keeps BlazePose's own readings of every shot in ``--keep`` (computed
once: ``track_shot``'s output, the floor's shift at the feet and the head cue; their 2D keypoints and masks
are the stored tracks'), then re-fits the bodies with the labelling settings given
(:class:`multithumbs.perception.facing.FacingConfig`). Only the fitting, the labelling and the method run
again, against 17 minutes for the bench from nothing.

    multithumbs bench --suite standard --from-pixels --json > /dev/null     # once: the stored inputs
    PYTHONPATH=. .venv/bin/python benchmarks/facing_refit.py [--keep /tmp/readings --facing turn_cost=4]
        [--method align.w_camera_prior=0.1] [--scenes s01_two_people_20deg,...] [--variants full,no_align]

Prints each scene's W-MPJPE, WA-MPJPE, MPJPE and IDs, then the frame-weighted means the bench prints.
With no settings the figures are the bench's own (session 26 used it to choose ``turn_cost``, session 27
the alignment's ``w_camera_prior``).
"""

from __future__ import annotations

import argparse
import pickle
import sys
from pathlib import Path

import multithumbs  # noqa: F401  (before numpy and torch: it pins the CPU kernels, multithumbs/cpu_kernels.py)
import numpy as np


def config_overrides(cls, text: str | None, flag: str) -> dict[str, float | bool]:
    """``name=value,...`` as keyword arguments of the dataclass ``cls``, each of its field's type (parsed as
    ``multithumbs run --set`` parses, :func:`multithumbs.overrides.parse_assignments`)."""
    from multithumbs.errors import InputError
    from multithumbs.overrides import parse_assignments

    defaults = {name: f.default for name, f in cls.__dataclass_fields__.items()
                if isinstance(f.default, bool | int | float)}
    out: dict[str, float | bool] = {}
    for item in filter(None, (part.strip() for part in (text or "").split(","))):
        name, _, text_value = (part.strip() for part in item.partition("="))
        if name not in defaults or not text_value:
            raise InputError(f"{flag} {item!r}: expected name=value with a name of {', '.join(sorted(defaults))}")
        value = parse_assignments([f"{name}={text_value}"], flag)[name]
        kind = type(defaults[name])  # bool, int or float, as the field's default
        if type(value) is not kind and not (kind is float and type(value) is int):
            raise InputError(f"{flag} {item!r}: {value!r} is not a {kind.__name__}")
        out[name] = value
    return out


def stored_inputs(config, store) -> tuple:
    """The scene's pixel inputs as the bench stored them (``shots, tracks, trajectories, spaces, ...``)."""
    from multithumbs.bench_sources import pixel_input_params
    from multithumbs.errors import InputError
    from multithumbs.synth.config import config_to_json

    cached = store.load(pixel_input_params(config_to_json(config)))
    if cached is None:
        raise InputError(f"{config.name}: no pixel inputs stored for this code under MULTITHUMBS_CACHE; "
                         f"run `multithumbs bench --from-pixels` first")
    return cached


def keep_readings(config, body, tracks, path: Path) -> list[dict]:
    """BlazePose's readings of each shot of a scene (computed once, then read from ``path``)."""
    if path.is_file():
        with path.open("rb") as f:
            return pickle.load(f)
    import tempfile

    from multithumbs.perception.blazepose_backend import (BlazePoseConfig, person_proposals, shot_face_evidence,
                                                          shot_floor_flow)
    from multithumbs.perception.blazepose_models import BlazePose
    from multithumbs.perception.pose_tracking import track_shot
    from multithumbs.synth.files import write_video
    from multithumbs.synth.scene import synthesize
    from multithumbs.video import read_frames

    video = synthesize(config, body)
    with tempfile.TemporaryDirectory() as tmp:  # encoded and decoded as the bench does
        frames = read_frames(write_video(Path(tmp) / "video.mp4", video.frames, video.truth.world.fps))
    settings = BlazePoseConfig()
    model, people = BlazePose(num_threads=settings.num_threads), person_proposals(settings)
    readings = []
    for track in tracks:
        shot = list(frames[track.start_frame:track.start_frame + track.valid.shape[1]])
        poses = track_shot(shot, model, settings.tracker, people=people)
        kept = np.isin(poses.track_ids, track.track_ids)  # the stored tracks lack those of no one (floor_check)
        if not (np.array_equal(poses.track_ids[kept], track.track_ids)
                and np.array_equal(poses.valid[kept], track.valid)):
            raise RuntimeError(f"{config.name}: BlazePose's tracks differ from the stored ones (another CPU's kernels?)")
        readings.append({"poses": poses, "floor": shot_floor_flow(shot, poses, settings),
                         "face": shot_face_evidence(shot, poses, settings)})
    partial = path.with_suffix(".partial")
    with partial.open("wb") as f:
        pickle.dump(readings, f)
    partial.replace(path)
    return readings


def refit_tracks(tracks, readings, body, facing) -> list:
    """The stored tracks with their bodies fitted again under ``facing`` (appearance kept: same masks), for
    the people both have (the fit drops tracks of no one, :mod:`multithumbs.perception.floor_check`)."""
    from dataclasses import replace

    from multithumbs.perception.blazepose_backend import BlazePoseConfig, poses_to_tracks
    from multithumbs.perception.floor_check import keep_people

    out = []
    for k, (old, r) in enumerate(zip(tracks, readings)):
        new = poses_to_tracks(r["poses"], k, old.start_frame, old.K, old.image_size, body, BlazePoseConfig().fit,
                              facing, r["floor"], r["face"])
        new = keep_people(new, np.isin(new.track_ids, old.track_ids))
        rows = [int(np.flatnonzero(old.track_ids == i)[0]) for i in new.track_ids]
        out.append(replace(new, appearance=old.appearance[rows], appearance_valid=old.appearance_valid[rows]))
    return out


class _Refitted:
    """An input cache that serves the stored inputs with the re-fitted tracks (never saves)."""

    def __init__(self, inputs: tuple, tracks: list):
        self.inputs, self.tracks = inputs, tracks

    def load(self, params: dict) -> tuple:
        return (self.inputs[0], self.tracks, *self.inputs[2:])

    def save(self, params: dict, value: tuple) -> None:
        raise AssertionError("the re-fitted inputs are not stored")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--keep", default=None, help="folder for BlazePose's readings (one file per scene); "
                                                      "needed with --facing")
    parser.add_argument("--facing", default=None, help="FacingConfig overrides, name=value,... (default: none, "
                                                       "the stored bodies)")
    parser.add_argument("--method", default=None, help="MethodConfig overrides, section.name=value,... as "
                                                       "`multithumbs run --set` takes (default: none)")
    parser.add_argument("--scenes", default=None, help="comma-separated standard-suite scenes (default: all 12)")
    parser.add_argument("--variants", default="full,no_align", help="comma-separated variants")
    args = parser.parse_args(argv)

    from multithumbs.bench import check_variants, run_scene_results, scene_metrics
    from multithumbs.body.model import load_body_model
    from multithumbs.determinism import fix_threads
    from multithumbs.errors import InputError
    from multithumbs.metrics.evaluate import evaluate
    from multithumbs.overrides import method_config, parse_assignments
    from multithumbs.perception.facing import FacingConfig
    from multithumbs.synth.commands import pixel_input_cache
    from multithumbs.synth.suite import suite

    try:
        facing = FacingConfig(**config_overrides(FacingConfig, args.facing, "--facing"))
        method = method_config("full", parse_assignments(filter(None, (args.method or "").split(",")), "--method"))
        if args.facing and not args.keep:
            raise InputError("--facing: needs --keep, the folder for BlazePose's readings")
        variants = check_variants(args.variants.split(","))
        configs = suite("standard")
        if args.scenes:
            names = args.scenes.split(",")
            unknown = sorted(set(names) - {c.name for c in configs})
            if unknown:
                raise InputError(f"--scenes: unknown {', '.join(unknown)}")
            configs = [c for c in configs if c.name in names]
        fix_threads()
        body = load_body_model()
        store = pixel_input_cache()
        keep = Path(args.keep) if args.facing else None
        if keep is not None:
            keep.mkdir(parents=True, exist_ok=True)
        rows = {}
        for config in configs:
            inputs = stored_inputs(config, store)
            tracks = inputs[1]
            if keep is not None:
                readings = keep_readings(config, body, inputs[1], keep / f"{config.name}.pkl")
                tracks = refit_tracks(inputs[1], readings, body, facing)
            truth, results = run_scene_results(config, variants, body, base=method, inputs="pixels",
                                               input_cache=_Refitted(inputs, tracks))
            rows[config.name] = {v: scene_metrics(evaluate(r, truth, body))[0] for v, r in results.items()}
            print(config.name[:28].ljust(28), "  ".join(
                f"{v} {m['w_mpjpe']:6.0f}/{m['wa_mpjpe']:4.0f}/{m['mpjpe']:4.0f} mm {m['ids']:.0f} IDs"
                for v, m in rows[config.name].items()), flush=True)
    except InputError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    print(f"facing: {facing if keep is not None else 'the stored bodies'}; method: {args.method or 'defaults'}")
    for v in variants:
        frames = np.array([r[v]["scored_frames"] for r in rows.values()], float)
        mean = {k: float((np.array([r[v][k] for r in rows.values()]) * frames).sum() / frames.sum())
                for k in ("w_mpjpe", "wa_mpjpe")}
        ids = [r[v]["ids"] for r in rows.values()]
        print(f"{v}: W-MPJPE {mean['w_mpjpe']:.1f} mm, WA-MPJPE {mean['wa_mpjpe']:.1f} mm (frame-weighted), "
              f"{sum(ids):.0f} IDs, {sum(i == 0 for i in ids)} of {len(ids)} scenes at 0")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
