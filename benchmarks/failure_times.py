"""Time from `multithumbs` start to its one-line error, for refusals before the flow and failures inside it.

Each case runs ``--repeats`` times in a fresh interpreter (as a user runs it); prints the median seconds to
the ``error:`` line, to the process's exit, and the number of stderr lines. ``--repo`` runs another
checkout's code (e.g. the previous commit's) for a before/after comparison.

    .venv/bin/python benchmarks/failure_times.py [--repeats 3] [--repo PATH]
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def timed(args: list[str], env: dict, prelude: str = "", cwd: Path | None = None) -> tuple[float, float, int, str]:
    """Seconds to the first ``error:`` line, seconds to exit, stderr line count, the error line."""
    code = f"import sys\n{prelude}\nsys.argv = ['multithumbs', *{args!r}]\nfrom multithumbs.cli import main\nmain()\n"
    start = time.perf_counter()
    process = subprocess.Popen([sys.executable, "-c", code], env=env, cwd=cwd, stdout=subprocess.DEVNULL,
                               stderr=subprocess.PIPE, text=True)
    first, lines, error = None, 0, ""
    for line in process.stderr:
        lines += 1
        if line.startswith("error:") and first is None:
            first, error = time.perf_counter() - start, line.strip()
    process.wait()
    end = time.perf_counter() - start
    return (first if first is not None else float("nan")), end, lines, error


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--repo", type=Path, default=Path(__file__).resolve().parents[1])
    args = parser.parse_args()
    work = Path(tempfile.mkdtemp(prefix="mt_failures_"))
    env = {**os.environ, "PYTHONPATH": str(args.repo.resolve()), "MULTITHUMBS_CACHE": str(work / "cache")}
    for name, frames in (("a", 8), ("b", 12)):
        subprocess.run([sys.executable, "-m", "multithumbs.cli", "synth", "--out", str(work / name), "--people", "2",
                        "--shots", "2", "--frames", str(frames), "--width", "320", "--height", "180"],
                       env=env, cwd=args.repo, check=True, capture_output=True)
    video, pkl = str(work / "a" / "video.mp4"), f"phalp:{work / 'a' / 'perception.pkl'}"
    out = str(work / "o")
    cases = [
        ("missing video", ["run", str(work / "missing.mp4"), "--out", out, "--perception", pkl], ""),
        ("pickle not trusted", ["run", video, "--out", out, "--perception", pkl], ""),
        ("hmr2 not installed", ["run", video, "--out", out, "--perception", "hmr2"], ""),
        ("unknown --set", ["run", video, "--out", out, "--perception", pkl, "--trust-pickle", "--set", "reid.x=1"], ""),
        ("scenedetect missing (shots)", ["shots", video], "sys.modules['scenedetect'] = None"),
        ("perception disagrees (in flow)", ["run", video, "--out", out, "--perception",
                                            f"phalp:{work / 'b' / 'perception.pkl'}", "--trust-pickle"], ""),
    ]
    print(f"{'case':34s} {'to error line':>14s} {'to exit':>8s} {'lines':>6s}   (medians of {args.repeats}; "
          f"{args.repo})")
    for label, argv, prelude in cases:
        results = []
        for _ in range(args.repeats):
            shutil.rmtree(out, ignore_errors=True)
            results.append(timed(argv, env, prelude, cwd=args.repo))  # cwd: `-c` puts it first on sys.path
        first = statistics.median(r[0] for r in results)
        end = statistics.median(r[1] for r in results)
        lines = statistics.median(r[2] for r in results)
        print(f"{label:34s} {first:12.1f} s {end:6.1f} s {lines:6.0f}   {results[-1][3][:90]}")
    shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
