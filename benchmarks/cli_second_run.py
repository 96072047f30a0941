"""`multithumbs demo` as a user runs it: a cold run into an empty output folder, then the same command again
(`--overwrite`: every stage is served from OUT/store, the flow still runs), each in a fresh process, timed
end to end. ``--dashboard`` repeats the pair with `multithumbs dashboard` running (the CLI then sends its runs
to it instead of starting a server). Prints medians of ``--repeats`` and the ratio warm / cold.

    .venv/bin/python benchmarks/cli_second_run.py [--repeats 3] [--scene s09_crossing_at_cut] [--dashboard]
"""

from __future__ import annotations

import argparse
import os
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import time
import urllib.request
from pathlib import Path


def cli(*args: str, env: dict) -> float:
    start = time.perf_counter()
    subprocess.run([sys.executable, "-m", "multithumbs.cli", *args], env=env, check=True,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - start


def pairs(repeats: int, scene: str, work: Path, env: dict) -> tuple[float, float]:
    colds, warms = [], []
    for r in range(repeats):
        out = work / f"demo{r}"
        shutil.rmtree(out, ignore_errors=True)
        colds.append(cli("demo", "--out", str(out), "--scene", scene, env=env))
        warms.append(cli("demo", "--out", str(out), "--scene", scene, "--overwrite", env=env))
        print(f"  run {r}: cold {colds[-1]:.1f} s, warm {warms[-1]:.1f} s", flush=True)
    return statistics.median(colds), statistics.median(warms)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--scene", default="s09_crossing_at_cut")
    parser.add_argument("--dashboard", action="store_true")
    args = parser.parse_args()
    work = Path(tempfile.mkdtemp(prefix="mt_cli_rerun_"))
    env = {k: v for k, v in os.environ.items() if k != "PREFECT_API_URL"}
    env.update(MULTITHUMBS_CACHE=str(work / "cache"), PYTHONPATH=str(Path(__file__).resolve().parents[1]))
    cli("synth", "--out", str(work / "warmup"), "--frames", "4", env=env)  # the procedural body's cache
    cold, warm = pairs(args.repeats, args.scene, work, env)
    print(f"{args.scene}, temporary server: cold {cold:.1f} s, warm {warm:.1f} s, warm / cold = {warm / cold:.3f}")
    if args.dashboard:
        port = "4391"
        dash = subprocess.Popen([sys.executable, "-m", "multithumbs.cli", "dashboard", "--port", port], env=env,
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
        try:
            for _ in range(120):
                try:
                    urllib.request.urlopen(f"http://127.0.0.1:{port}/api/health", timeout=1)
                    break
                except OSError:
                    time.sleep(1)
            time.sleep(2)  # the dashboard's record is written once the server answers
            cold, warm = pairs(args.repeats, args.scene, work, env)
            print(f"{args.scene}, dashboard running: cold {cold:.1f} s, warm {warm:.1f} s, "
                  f"warm / cold = {warm / cold:.3f}")
        finally:
            os.killpg(dash.pid, signal.SIGINT)
            dash.wait(timeout=60)
    shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
