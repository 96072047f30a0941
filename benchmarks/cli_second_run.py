"""`multithumbs demo` as a user runs it: a cold run into an empty output folder with no Prefect server
running, then the same command again (`--overwrite`: every stage is served from OUT/store, the flow still
runs, on the server the cold run kept: flows/local_api.py), each in a fresh process, timed end to end.
``--unkept`` repeats the pair with ``MULTITHUMBS_API_LINGER=0`` (each command starts and stops its own
server, as before servers were kept); ``--dashboard`` with `multithumbs dashboard` running (the CLI then
sends its runs to it). Prints medians of ``--repeats`` and the ratio warm / cold.

    .venv/bin/python benchmarks/cli_second_run.py [--repeats 3] [--scene s09_crossing_at_cut] [--unkept] [--dashboard]
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

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # this checkout's flows/, as the CLI runs below


def cli(*args: str, env: dict) -> float:
    start = time.perf_counter()
    subprocess.run([sys.executable, "-m", "multithumbs.cli", *args], env=env, check=True,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - start


def pairs(repeats: int, scene: str, work: Path, env: dict) -> tuple[float, float]:
    from flows.local_api import stop_kept

    colds, warms = [], []
    for r in range(repeats):
        out = work / f"demo{r}"
        shutil.rmtree(out, ignore_errors=True)
        stop_kept(work / "cache" / "prefect")  # cold: no server running either
        colds.append(cli("demo", "--out", str(out), "--scene", scene, env=env))
        warms.append(cli("demo", "--out", str(out), "--scene", scene, "--overwrite", env=env))
        print(f"  run {r}: cold {colds[-1]:.1f} s, warm {warms[-1]:.1f} s", flush=True)
    stop_kept(work / "cache" / "prefect")
    return statistics.median(colds), statistics.median(warms)


def report(label: str, scene: str, cold: float, warm: float) -> None:
    print(f"{scene}, {label}: cold {cold:.1f} s, warm {warm:.1f} s, warm / cold = {warm / cold:.3f}", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--scene", default="s09_crossing_at_cut")
    parser.add_argument("--unkept", action="store_true", help="also with MULTITHUMBS_API_LINGER=0")
    parser.add_argument("--dashboard", action="store_true")
    args = parser.parse_args()
    work = Path(tempfile.mkdtemp(prefix="mt_cli_rerun_"))
    env = {k: v for k, v in os.environ.items() if k not in ("PREFECT_API_URL", "PREFECT_HOME",
                                                              "MULTITHUMBS_API_LINGER")}
    env.update(MULTITHUMBS_CACHE=str(work / "cache"), PYTHONPATH=str(Path(__file__).resolve().parents[1]))
    cli("synth", "--out", str(work / "warmup"), "--frames", "4", env=env)  # the procedural body's cache
    report("server kept by the cold run", args.scene, *pairs(args.repeats, args.scene, work, env))
    if args.unkept:
        report("MULTITHUMBS_API_LINGER=0 (a server per command)", args.scene,
               *pairs(args.repeats, args.scene, work, {**env, "MULTITHUMBS_API_LINGER": "0"}))
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
            report("dashboard running", args.scene, *pairs(args.repeats, args.scene, work, env))
        finally:
            os.killpg(dash.pid, signal.SIGINT)
            dash.wait(timeout=60)
    shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
