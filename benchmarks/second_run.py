"""Second run of the synthetic flow against the first: everything is served from the artifact store.

Runs ``flows.reconstruct.reconstruct_synthetic`` on one standard-suite scene into an empty store, then
again into the same store (nothing is computed: every stage's artifact exists), ``--repeats`` times with a
fresh store each, and prints the median wall times and their ratio (target: the second under a tenth of
the first). Prefect runs on its ephemeral API, as in ``multithumbs demo``.

    .venv/bin/python benchmarks/second_run.py [--repeats 3] [--scene s09_crossing_at_cut]
"""

from __future__ import annotations

import argparse
import os
import statistics
import tempfile
import time


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--scene", default="s09_crossing_at_cut")
    args = parser.parse_args()
    work = tempfile.mkdtemp(prefix="mt_rerun_")
    os.environ.setdefault("PREFECT_HOME", os.path.join(work, "prefect"))
    os.environ.setdefault("PREFECT_SERVER_EPHEMERAL_STARTUP_TIMEOUT_SECONDS", "90")
    os.environ.setdefault("PREFECT_SERVER_ANALYTICS_ENABLED", "false")
    os.environ.setdefault("PREFECT_LOGGING_LEVEL", "WARNING")
    from flows.reconstruct import reconstruct_synthetic
    from multithumbs.synth.scene import config_to_json
    from multithumbs.synth.suite import suite_scene

    scene = config_to_json(suite_scene("standard", args.scene))
    firsts, seconds = [], []
    for r in range(args.repeats):
        out, store = os.path.join(work, f"out{r}"), os.path.join(work, f"store{r}")
        os.makedirs(out)
        start = time.perf_counter()
        reconstruct_synthetic(scene, out, store)
        firsts.append(time.perf_counter() - start)
        start = time.perf_counter()
        reconstruct_synthetic(scene, out, store)
        seconds.append(time.perf_counter() - start)
        print(f"run {r}: first {firsts[-1]:.1f} s, second {seconds[-1]:.2f} s")
    first, second = statistics.median(firsts), statistics.median(seconds)
    print(f"{args.scene}: first {first:.1f} s, second {second:.2f} s (medians of {args.repeats}); "
          f"second / first = {second / first:.3f}")


if __name__ == "__main__":
    main()
