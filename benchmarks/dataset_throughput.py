"""Throughput of the dataset flow with the Dask task runner: 4 synthetic videos, 1 worker vs 2 workers.

Every run starts from an empty artifact store (nothing cached), so it times synthesis, simulated inputs,
alignment, propagation, re-ID, post-processing and evaluation of all videos. Prints the median wall time
of ``--repeats`` runs per worker count and the throughput in videos per minute.

    .venv/bin/python benchmarks/dataset_throughput.py [--repeats 3] [--frames 60]
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import statistics
import tempfile
import time


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--frames", type=int, default=60)
    parser.add_argument("--videos", type=int, default=4)
    args = parser.parse_args()
    work = tempfile.mkdtemp(prefix="mt_throughput_")
    os.environ.setdefault("PREFECT_HOME", os.path.join(work, "prefect"))
    os.environ.setdefault("PREFECT_SERVER_EPHEMERAL_STARTUP_TIMEOUT_SECONDS", "90")
    os.environ.setdefault("PREFECT_LOGGING_LEVEL", "WARNING")

    from flows.dataset import reconstruct_dataset
    from multithumbs.synth.scene import SceneConfig, config_to_json

    base = SceneConfig(name="v", num_people=3, num_shots=2, num_frames=args.frames, image_size=(180, 320),
                       cut_angle_deg=40)
    items = [{"name": f"v{i}", "scene": config_to_json(dataclasses.replace(base, name=f"v{i}", seed=500 + i))}
             for i in range(args.videos)]
    reconstruct_dataset(items[:1], os.path.join(work, "warmup"), os.path.join(work, "warmup_store"))  # API start-up
    times: dict[int, list[float]] = {1: [], 2: []}
    for r in range(args.repeats):
        for workers in (1, 2):
            run = os.path.join(work, f"w{workers}_r{r}")
            start = time.perf_counter()
            reconstruct_dataset(items, run, os.path.join(run, "store"), runner="dask", workers=workers)
            times[workers].append(time.perf_counter() - start)
            print(f"run {r}: {workers} worker(s): {times[workers][-1]:.1f} s", flush=True)
    print(f"\ndataset flow, {args.videos} synthetic videos ({args.frames} frames, 3 people, 2 shots, 320x180), "
          f"Dask runner, empty store each run, {args.repeats} runs:")
    for workers, values in times.items():
        median = statistics.median(values)
        print(f"  {workers} worker(s): median {median:.1f} s  ->  {60 * args.videos / median:.2f} videos/min")
    print(f"  speed-up 2 vs 1 workers: {statistics.median(times[1]) / statistics.median(times[2]):.2f}x")


if __name__ == "__main__":
    main()
