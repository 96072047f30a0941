"""Seconds to synthesise a 120-frame 640x360 scene with 3 people (target <= 60 s), median over runs.

Usage: python benchmarks/synthesize.py [--runs N] [--frames T] [--people P]
Prints one line per run and the median; also the split between posing+rendering and writing files.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time

from multithumbs.body.model import load_body_model
from multithumbs.synth.files import prepare_output_dir, write_synthetic
from multithumbs.synth.scene import SceneConfig, synthesize


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--frames", type=int, default=120)
    parser.add_argument("--people", type=int, default=3)
    args = parser.parse_args()
    body = load_body_model()
    totals = []
    for run in range(args.runs):
        config = SceneConfig(num_people=args.people, num_frames=args.frames, seed=run, image_size=(360, 640))
        with tempfile.TemporaryDirectory() as tmp:
            start = time.perf_counter()
            video = synthesize(config, body)
            rendered = time.perf_counter()
            write_synthetic(prepare_output_dir(tmp), video)
            done = time.perf_counter()
        totals.append(done - start)
        print(f"run {run}: {done - start:.1f} s total ({rendered - start:.1f} s pose+render, "
              f"{done - rendered:.1f} s writing video, ground truth and contact sheet)")
    print(f"median: {statistics.median(totals):.1f} s for {args.frames} frames 640x360, {args.people} people "
          f"(target <= 60 s)")


if __name__ == "__main__":
    main()
