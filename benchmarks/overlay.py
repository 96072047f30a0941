"""Seconds per frame of the overlay video at 640x360 with 4 people, on one core.

Synthesises a 4-person two-shot scene (the procedural body, or $MULTITHUMBS_SMPL_MODEL), then times
(a) one overlay panel per frame: posing the valid people with the body model, rasterising and shading
their meshes, blending and annotating (:func:`multithumbs.viz.overlay.overlay_image`), and (b) the whole
``write_overlay_video`` per frame (decoding the input, (a), MPEG-4 encoding), without and with the
ground-truth panel. Prints medians over ``--runs`` runs (each over all frames) after a warm-up.

    .venv/bin/python benchmarks/overlay.py [--runs 5] [--frames 8]
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one core, before numpy loads its BLAS

import argparse
import statistics
import tempfile
import time
from pathlib import Path

import cv2
import multithumbs  # noqa: F401  (before numpy and torch: it pins the CPU kernels, multithumbs/cpu_kernels.py)
import torch

from multithumbs.body.model import load_body_model
from multithumbs.synth.files import write_video
from multithumbs.synth.scene import SceneConfig, synthesize
from multithumbs.viz.overlay import overlay_image, write_overlay_video


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=5, help="timed runs (>= 3)")
    parser.add_argument("--frames", type=int, default=8, help="frames of the scene")
    args = parser.parse_args()
    cv2.setNumThreads(1)
    torch.set_num_threads(1)
    body = load_body_model()
    video = synthesize(SceneConfig(num_people=4, num_shots=2, num_frames=args.frames, seed=7, image_size=(360, 640)),
                       body)
    world = video.truth.world
    people = world.valid.sum(axis=0)
    print(f"scene: 640x360, {args.frames} frames, people per frame {people.min()}-{people.max()}, "
          f"body {body.source} ({body.num_vertices} vertices, {len(body.faces)} faces)")
    overlay_image(video.frames[0], world, 0, body)  # warm-up

    panel = []
    for _ in range(args.runs):
        start = time.perf_counter()
        for f in range(world.num_frames):
            overlay_image(video.frames[f], world, f, body)
        panel.append((time.perf_counter() - start) / world.num_frames)
    print(f"overlay panel (pose + rasterise + blend + annotate): median {statistics.median(panel):.3f} s/frame "
          f"(min {min(panel):.3f}, max {max(panel):.3f}, {args.runs} runs)")

    with tempfile.TemporaryDirectory() as tmp:
        path = write_video(Path(tmp) / "video.mp4", video.frames, world.fps)
        for label, truth in (("overlay video", None), ("overlay video with truth panel", video.truth)):
            runs = []
            for i in range(args.runs):
                start = time.perf_counter()
                write_overlay_video(Path(tmp) / f"o{i}.mp4", world, path, body, truth)
                runs.append((time.perf_counter() - start) / world.num_frames)
            print(f"{label} (decode + panels + encode): median {statistics.median(runs):.3f} s/frame "
                  f"(min {min(runs):.3f}, max {max(runs):.3f}, {args.runs} runs)")


if __name__ == "__main__":
    main()
