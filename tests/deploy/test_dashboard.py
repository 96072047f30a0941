"""`multithumbs dashboard` serves Prefect's UI and API on the CLI's Prefect home; while it runs, a CLI run goes
to it (no server of its own) and shows in it; stopping it (Ctrl-C) removes its record."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import pytest

from tests.deploy.stack import call_api, free_port, healthy


@pytest.mark.slow  # ~2 min on a busy 2-core machine: two scenes, a server, a flow run
@pytest.mark.timeout(600)
def test_cli_runs_show_in_the_dashboard(tmp_path):
    cache = tmp_path / "cache"
    env = {k: v for k, v in os.environ.items() if k != "PREFECT_API_URL"}
    env.update(MULTITHUMBS_CACHE=str(cache), PREFECT_SERVER_ANALYTICS_ENABLED="false")
    scenes = {}
    for name, frames in (("a", 8), ("b", 12)):
        scenes[name] = tmp_path / name
        done = subprocess.run([sys.executable, "-m", "multithumbs.cli", "synth", "--out", str(scenes[name]),
                               "--people", "2", "--shots", "2", "--frames", str(frames), "--width", "320",
                               "--height", "180"], env=env, capture_output=True, text=True, timeout=600)
        assert done.returncode == 0, done.stderr
    port = free_port()
    api = f"http://127.0.0.1:{port}/api"
    record = cache / "prefect" / "multithumbs-dashboard.json"
    dashboard = subprocess.Popen([sys.executable, "-m", "multithumbs.cli", "dashboard", "--port", str(port)], env=env,
                                 start_new_session=True, stdout=open(tmp_path / "dashboard.log", "w"),
                                 stderr=subprocess.STDOUT)
    try:
        deadline = time.time() + 180
        while not record.exists():
            assert dashboard.poll() is None, (tmp_path / "dashboard.log").read_text()
            assert time.time() < deadline, "the dashboard did not start"
            time.sleep(1)
        assert healthy(api)
        # A run that fails inside its flow (perception of another video) is still a run of the dashboard.
        run = subprocess.run([sys.executable, "-m", "multithumbs.cli", "run", str(scenes["a"] / "video.mp4"), "--out",
                              str(tmp_path / "o"), "--perception", f"phalp:{scenes['b'] / 'perception.pkl'}",
                              "--trust-pickle"], env=env, capture_output=True, text=True, timeout=600)
        assert run.returncode == 2 and len(run.stderr.strip().splitlines()) == 1, run.stderr
        log = run.stderr.split("(details: ")[1].rstrip(")\n")
        # Sent to the dashboard, not to a server of its own (both would write the same database).
        assert f"Prefect API: dashboard at {api}" in open(log).read()
        runs = call_api(f"{api}/flow_runs/filter", "POST", {})
        assert [r["state_type"] for r in runs if r["flow_id"]] == ["FAILED"], runs
    finally:
        if dashboard.poll() is None:
            os.killpg(dashboard.pid, signal.SIGINT)
            try:
                dashboard.wait(timeout=60)
            except subprocess.TimeoutExpired:
                os.killpg(dashboard.pid, signal.SIGKILL)
                dashboard.wait(timeout=10)
    assert not record.exists()
