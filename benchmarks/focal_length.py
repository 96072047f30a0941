"""Focal length from the pixels on the standard suite: estimate, truth, error and source per scene.

For every scene: synthesise it, encode it as MPEG-4 and decode it (as ``bench --from-pixels`` does), then
:func:`multithumbs.scene.focal.estimate_focal` as ``multithumbs run`` runs it without ``--intrinsics``
(people from the simulated perception's 2D keypoints, which stand in for the perception backend's), and
beside it each source alone on every scene: the moving camera's, the straight edges' (vanishing points)
and the people's heights. Medians over
``--runs`` perception seeds (the moving-camera estimate does not depend on them).

    .venv/bin/python benchmarks/focal_length.py [--scenes s04,s10,s11] [--runs 1] [--fov DEG] [--json OUT]

``--fov`` renders every scene with that horizontal field of view instead of the suite's 62 degrees.
"""

from __future__ import annotations

import argparse
import json
import statistics
import tempfile
import time
from pathlib import Path


def run_scene(config, runs: int) -> dict:
    from multithumbs.body.model import load_body_model
    from multithumbs.scene.focal import estimate_focal, motion_estimate
    from multithumbs.scene.focal_lines import focal_from_lines
    from multithumbs.scene.focal_heights import focal_from_heights
    from multithumbs.synth.files import write_video
    from multithumbs.synth.perception import simulate_perception
    from multithumbs.synth.scene import synthesize
    from multithumbs.video import read_frames

    body = load_body_model()
    video = synthesize(config, body)
    with tempfile.TemporaryDirectory() as tmp:
        frames = read_frames(write_video(Path(tmp) / "video.mp4", video.frames, video.truth.world.fps))
    ranges = video.truth.world.shots().ranges
    truth = float(video.truth.world.K[0, 0, 0])
    start = time.perf_counter()
    motion = motion_estimate(frames, ranges)
    motion_seconds = time.perf_counter() - start
    start = time.perf_counter()
    lines = focal_from_lines(frames, ranges)
    lines_seconds = time.perf_counter() - start
    # As frames_estimate orders them (lines first), from the two answers already in hand.
    from_frames = lines if lines[0] is not None else motion if motion[0] is not None else \
        (None, f"lines: {lines[1]}; moving camera: {motion[1]}")
    chosen, heights = [], []
    for seed in range(runs):
        tracks = simulate_perception(video, body, seed=seed)
        chosen.append(estimate_focal(frames, ranges, tracks=tracks, from_frames=from_frames))
        h, _ = focal_from_heights(tracks, frames.shape[1:3])
        heights.append(h.focal_px if h is not None else float("nan"))
    final = sorted(chosen, key=lambda e: e.focal_px)[len(chosen) // 2]
    return {"scene": config.name, "truth": truth, "estimate": final.focal_px, "source": final.source,
            "detail": final.detail, "moving": [config.camera_is_moving(k) for k in range(config.num_shots)],
            "motion": motion[0].focal_px if motion[0] is not None else None, "motion_why": motion[1],
            "motion_seconds": motion_seconds, "heights": statistics.median(heights),
            "lines": lines[0].focal_px if lines[0] is not None else None, "lines_why": lines[1],
            "lines_seconds": lines_seconds}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", default="", help="comma-separated scene name prefixes (default: all)")
    parser.add_argument("--runs", type=int, default=1)
    parser.add_argument("--fov", type=float, default=0.0, help="horizontal field of view (default: the suite's)")
    parser.add_argument("--json", default="")
    args = parser.parse_args()
    from multithumbs.determinism import fix_threads
    from multithumbs.synth.suite import suite

    fix_threads()
    wanted = [s for s in args.scenes.split(",") if s]
    configs = [c for c in suite("standard") if not wanted or any(c.name.startswith(w) for w in wanted)]
    if args.fov:
        import dataclasses

        configs = [dataclasses.replace(c, horizontal_fov_deg=args.fov) for c in configs]
    print("| scene | cameras | truth (px) | estimate (px) | error | source | moving-camera path | lines alone | error "
          "| heights alone | error |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    rows = []
    for config in configs:
        r = run_scene(config, args.runs)
        rows.append(r)
        err = 100 * (r["estimate"] / r["truth"] - 1)
        herr = 100 * (r["heights"] / r["truth"] - 1)
        cams = "/".join("moving" if m else "static" for m in r["moving"])
        path = f"{r['motion']:.0f} px" if r["motion"] is not None else r["motion_why"]
        lines = (f"{r['lines']:.0f} ({r['lines_seconds']:.1f} s) | {100 * (r['lines'] / r['truth'] - 1):+.1f} %"
                 if r["lines"] is not None else f"{r['lines_why']} ({r['lines_seconds']:.1f} s) | -")
        print(f"| {r['scene']} | {cams} | {r['truth']:.0f} | {r['estimate']:.0f} | {err:+.1f} % | {r['source']} | "
              f"{path} ({r['motion_seconds']:.0f} s) | {lines} | {r['heights']:.0f} | {herr:+.1f} % |", flush=True)
    within = [abs(r["estimate"] / r["truth"] - 1) <= 0.10 for r in rows]
    print(f"within 10 %: {sum(within)}/{len(rows)}; median |error| "
          f"{100 * statistics.median(abs(r['estimate'] / r['truth'] - 1) for r in rows):.1f} %")
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=2))


if __name__ == "__main__":
    main()
