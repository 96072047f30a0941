"""A real deployment round trip: a Prefect server and a process worker on loopback, `prefect deploy` from
deploy/prefect.yaml, `prefect deployment run`, the flow's artifacts checked; everything started is stopped."""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
PREFECT = str(Path(sys.executable).with_name("prefect"))


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _healthy(url: str) -> bool:
    try:
        with urllib.request.urlopen(f"{url}/health", timeout=2) as response:
            return response.status == 200
    except OSError:
        return False


def _stop(process: subprocess.Popen, sig: int) -> None:
    """Stop a process group politely (``sig``), then for sure; the worker stops on SIGINT, not SIGTERM."""
    if process.poll() is None:
        os.killpg(process.pid, sig)
        try:
            process.wait(timeout=30)
        except subprocess.TimeoutExpired:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait(timeout=10)


def test_deploy_run_and_check_artifacts(tmp_path):
    port = _free_port()
    api = f"http://127.0.0.1:{port}/api"
    env = {**os.environ, "PREFECT_HOME": str(tmp_path / "prefect_home"), "PREFECT_API_URL": api,
           "PREFECT_SERVER_ANALYTICS_ENABLED": "false", "COLUMNS": "250", "PREFECT_LOGGING_LEVEL": "WARNING",
           "MULTITHUMBS_HOME": str(REPO), "MULTITHUMBS_CACHE": str(tmp_path / "cache")}
    logs = tmp_path / "logs"
    logs.mkdir()
    started: list[tuple[subprocess.Popen, int]] = []

    def start(name: str, *args: str, sig: int) -> subprocess.Popen:
        process = subprocess.Popen([PREFECT, *args], env=env, cwd=REPO, start_new_session=True,
                                   stdout=open(logs / f"{name}.log", "w"), stderr=subprocess.STDOUT)
        started.append((process, sig))
        return process

    def prefect(*args: str, timeout: float = 120) -> str:
        done = subprocess.run([PREFECT, *args], env=env, cwd=REPO, capture_output=True, text=True, timeout=timeout)
        assert done.returncode == 0, f"prefect {' '.join(args)}:\n{done.stdout}\n{done.stderr}"
        return done.stdout

    try:
        server = start("server", "server", "start", "--host", "127.0.0.1", "--port", str(port), sig=signal.SIGTERM)
        deadline = time.time() + 120
        while not _healthy(api):
            assert server.poll() is None, (logs / "server.log").read_text()
            assert time.time() < deadline, "server did not become healthy"
            time.sleep(1)
        prefect("work-pool", "create", "multithumbs-process", "--type", "process")
        prefect("--no-prompt", "deploy", "--prefect-file", "deploy/prefect.yaml", "--name", "synthetic-video",
                "--name", "nightly-standard", "--name", "standard-suite", "--name", "egohumans-weekly")
        for name in ("reconstruct-synthetic/synthetic-video", "reconstruct-dataset/nightly-standard",
                     "benchmark/standard-suite"):
            assert "multithumbs-process" in prefect("deployment", "inspect", name)
        assert "0 2 * * *" in prefect("deployment", "inspect", "reconstruct-dataset/nightly-standard")
        assert "0 3 * * 0" in prefect("deployment", "inspect", "dataset-benchmark/egohumans-weekly")
        start("worker", "worker", "start", "--pool", "multithumbs-process", sig=signal.SIGINT)

        out_dir, store = tmp_path / "run", tmp_path / "store"
        scene = {"name": "tiny", "num_people": 2, "num_shots": 2, "num_frames": 10, "seed": 41,
                 "image_size": [180, 320], "cut_angle_deg": 30}
        params = json.dumps({"scene": scene, "out_dir": str(out_dir), "store_url": str(store)})
        output = prefect("deployment", "run", "reconstruct-synthetic/synthetic-video", "--params", params,
                         "--watch", "--watch-timeout", "600", timeout=660)
        assert "finished successfully" in output, output
        metrics = json.loads((out_dir / "metrics.json").read_text())
        assert metrics["ids"] == 0
        for name in ("video.mp4", "ground_truth.npz", "result.npz"):
            assert (out_dir / name).stat().st_size > 0
        from storage.store import ArtifactStore

        stages = {ArtifactStore(store).record(k)["stage"] for k in ArtifactStore(store).keys()}
        assert stages == {"simulate_inputs", "align", "propagate", "reid", "post"}
    finally:
        for process, sig in reversed(started):
            _stop(process, sig)
    for process, _ in started:
        assert process.poll() is not None
