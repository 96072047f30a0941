"""Seconds for the method itself (scale, alignment, propagation, re-ID, post-processing) with the paper's
iteration counts, on a two-shot, four-person clip of 150, 300 and 600 frames (target: <= 20 s at 150 frames,
growing no faster than linearly). Inputs (simulated perception, simulated shared space and camera tracking)
are prepared outside the timing. Median over runs.

Usage: python benchmarks/method.py [--runs N] [--frames 150 300 600]
"""

from __future__ import annotations

import argparse
import statistics
import time

import multithumbs  # noqa: F401  (before numpy and torch: it pins the CPU kernels, multithumbs/cpu_kernels.py)
import torch

from multithumbs.body.model import load_body_model
from multithumbs.pipeline import MethodConfig, run_video
from multithumbs.synth.perception import simulate_perception
from multithumbs.synth.scene import SceneConfig, synthesize
from multithumbs.synth.simulated_geometry import simulate_camera_trajectory, simulate_shared_space


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--frames", type=int, nargs="+", default=[150, 300, 600])
    args = parser.parse_args()
    body = load_body_model()
    print(f"torch threads: {torch.get_num_threads()} (optimisation loops: align {MethodConfig().align.threads}, "
          f"post {MethodConfig().post.threads}); iterations {MethodConfig().align.iterations} + "
          f"post {MethodConfig().post.iterations}")
    medians = {}
    for frames in args.frames:
        config = SceneConfig(num_people=4, num_shots=2, num_frames=frames, seed=7, cut_angle_deg=45)
        video = synthesize(config, body)
        shots = video.truth.world.shots()
        tracks = simulate_perception(video, body)
        spaces = [simulate_shared_space(video, c) for c in range(len(shots.cut_frames))]
        trajectories = [simulate_camera_trajectory(video, k) for k in range(shots.num_shots)]
        times = []
        for run in range(args.runs):
            start = time.perf_counter()
            run_video(shots, tracks, trajectories, spaces, body, MethodConfig())
            times.append(time.perf_counter() - start)
        medians[frames] = statistics.median(times)
        print(f"{frames} frames: median {medians[frames]:.1f} s over {args.runs} runs "
              f"({', '.join(f'{t:.1f}' for t in times)}); {medians[frames] / frames * 1000:.0f} ms/frame")
    if len(medians) > 1:
        base = min(medians)
        for frames, t in medians.items():
            print(f"  time ratio vs {base} frames: {t / medians[base]:.2f} for {frames / base:.1f}x the frames")


if __name__ == "__main__":
    main()
