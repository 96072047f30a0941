"""The standard suite end to end with geometry FROM PIXELS beside the simulated-geometry figures.

For every scene: synthesise it, simulate perception (as in the benchmark), then run the full method twice —
once with the SIMULATED shared space and camera trajectories (the benchmark's stand-ins) and once with
cuts (scenedetect on the encoded MPEG-4), camera trajectories and shared spaces (pycolmap) computed from
the rendered pixels, people masked out by the simulated perception's masks, true intrinsics. Prints both
tables side by side (W-MPJPE, IDs) and the geometry's per-stage seconds.

    .venv/bin/python benchmarks/pixels_suite.py [--workers 2] [--scenes s01_two_people_20deg,...] [--json OUT]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path


def run_scene(name: str) -> dict:
    import numpy as np
    import torch

    torch.set_num_threads(1)
    from multithumbs.body.model import load_body_model
    from multithumbs.metrics.evaluate import evaluate
    from multithumbs.pipeline import MethodConfig, run_video
    from multithumbs.scene.geometry import scene_geometry
    from multithumbs.scene.shots import detect_shots
    from multithumbs.synth.files import write_video
    from multithumbs.synth.perception import simulate_perception
    from multithumbs.synth.scene import synthesize
    from multithumbs.synth.simulated_geometry import simulate_camera_trajectory, simulate_shared_space
    from multithumbs.synth.suite import suite_scene

    body = load_body_model()
    video = synthesize(suite_scene("standard", name), body)
    truth_shots = video.truth.world.shots()
    tracks = simulate_perception(video, body)
    out = {"scene": name}
    simulated = run_video(truth_shots, tracks, [simulate_camera_trajectory(video, k) for k in range(truth_shots.num_shots)],
                          [simulate_shared_space(video, c) for c in range(truth_shots.num_shots - 1)], body, MethodConfig())
    scores = evaluate(simulated, video.truth, body)
    out["simulated"] = {"w_mpjpe": float(scores["w_mpjpe"]), "ids": float(scores["ids"])}

    with tempfile.TemporaryDirectory() as tmp:
        path = write_video(Path(tmp) / "video.mp4", video.frames, video.truth.world.fps)
        start = time.perf_counter()
        shots = detect_shots(path)
        shot_seconds = time.perf_counter() - start
    out["cuts_exact"] = bool(np.array_equal(shots.cut_frames, truth_shots.cut_frames))
    if not out["cuts_exact"]:
        out["pixels"] = {"w_mpjpe": float("nan"), "ids": float("nan")}
        return out
    masks = np.concatenate([tr.people_mask() for tr in tracks])
    geometry = scene_geometry(video.frames, shots, video.truth.world.K, masks)
    result = run_video(shots, tracks, list(geometry.trajectories), list(geometry.spaces), body, MethodConfig())
    scores = evaluate(result, video.truth, body)
    out["pixels"] = {"w_mpjpe": float(scores["w_mpjpe"]), "ids": float(scores["ids"])}
    out["geometry_seconds"] = {"shots": shot_seconds, **geometry.seconds}
    out["fallbacks"] = [s.fallback for s in geometry.spaces if s.fallback]
    out["trajectory_sources"] = [t.source for t in geometry.trajectories]
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--scenes", default="")
    parser.add_argument("--json", default="")
    args = parser.parse_args()
    from multithumbs.synth.suite import suite

    names = [s for s in args.scenes.split(",") if s] or [c.name for c in suite("standard")]
    start = time.perf_counter()
    with ProcessPoolExecutor(args.workers) as pool:
        rows = list(pool.map(run_scene, names))
    wall = time.perf_counter() - start
    print(f"standard suite, full method, {len(rows)} scenes, {wall:.0f} s wall ({args.workers} workers)")
    print("| scene | cuts exact | W-MPJPE simulated | W-MPJPE pixels | IDs simulated | IDs pixels | fallbacks |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['scene']} | {r['cuts_exact']} | {r['simulated']['w_mpjpe']:.1f} | {r['pixels']['w_mpjpe']:.1f} | "
              f"{r['simulated']['ids']:.0f} | {r['pixels']['ids']:.0f} | {', '.join(r.get('fallbacks', [])) or '-'} |")
    sim = statistics.mean(r["simulated"]["w_mpjpe"] for r in rows)
    pix = statistics.mean(r["pixels"]["w_mpjpe"] for r in rows)
    zero_sim = sum(r["simulated"]["ids"] == 0 for r in rows)
    zero_pix = sum(r["pixels"]["ids"] == 0 for r in rows)
    print(f"| mean (unweighted) | | {sim:.1f} | {pix:.1f} | {zero_sim}/{len(rows)} zero | {zero_pix}/{len(rows)} zero | |")
    print(f"pixels / simulated W-MPJPE: {pix / sim:.2f}")
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=2))


if __name__ == "__main__":
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    main()
