"""deploy/README.md's steps, run in order as written: the first bash block, with the port and paths moved into
the test's own (free port, temporary folders, this interpreter's venv) and the benchmark's ~10 min run
replaced by `deployment inspect`. Everything it starts (server, worker) is stopped."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.deploy.stack import REPO, free_port

README = REPO / "deploy" / "README.md"


def readme_steps() -> str:
    return re.search(r"```bash\n(.*?)```", README.read_text(), re.S).group(1)


def test_the_gpu_deployment_is_not_in_the_file_step_3_deploys_with_all():
    """`--all` must not name a work pool the steps do not create (it exited 1 on multithumbs-gpu)."""
    import yaml

    steps = readme_steps()
    created = set(re.findall(r"work-pool create (\S+)", steps))
    spec = yaml.safe_load((REPO / "deploy" / "prefect.yaml").read_text())
    assert {d["work_pool"]["name"] for d in spec["deployments"]} <= created


@pytest.mark.slow
@pytest.mark.timeout(900)
def test_deploy_readme_steps_run_in_order(tmp_path):
    port = free_port()
    bin_dir = str(Path(sys.executable).parent)
    script = readme_steps().replace(".venv/bin/", f"{bin_dir}/").replace("4200", str(port))
    script = script.replace('"/tmp/', f'"{tmp_path}/')
    script = script.replace("deployment run 'benchmark/standard-suite' --watch",
                            "deployment inspect 'benchmark/standard-suite'")
    assert "standard-suite" in script and "s09_crossing_at_cut" in script
    env = {**os.environ, "PREFECT_HOME": str(tmp_path / "prefect_home"), "PREFECT_SERVER_ANALYTICS_ENABLED": "false",
           "PREFECT_LOGGING_LEVEL": "WARNING", "COLUMNS": "250", "MULTITHUMBS_CACHE": str(tmp_path / "cache"),
           "PYTHONPATH": os.pathsep.join(filter(None, [str(REPO), os.environ.get("PYTHONPATH")]))}
    env.pop("PREFECT_API_URL", None)
    # -e: stop at the first failing step; the background jobs (server, worker) share the script's process
    # group, stopped below: the worker on SIGINT, then the server on SIGTERM.
    # Output to a file: the background jobs keep a pipe open after the script ends.
    log = tmp_path / "steps.log"
    with open(log, "w") as fh:
        process = subprocess.Popen(["bash", "-e", "-c", script + "\necho STEPS-DONE\n"], cwd=REPO, env=env,
                                   start_new_session=True, stdout=fh, stderr=subprocess.STDOUT)
    try:
        process.wait(timeout=840)
    finally:
        for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGKILL):
            try:
                os.killpg(process.pid, sig)
            except ProcessLookupError:
                break
            time.sleep(5)
    output = log.read_text()
    assert "STEPS-DONE" in output, output[-5000:]
    assert "finished successfully" in output, output[-5000:]
    metrics = json.loads((tmp_path / "s09" / "metrics.json").read_text())
    assert metrics["ids"] == 0
    from storage.store import ArtifactStore
    from multithumbs.synth.suite import suite_scene

    store = ArtifactStore(tmp_path / "store")
    key = next(k for k in store.keys() if store.record(k)["stage"] == "simulate_inputs")
    scene = store.record(key)["attributes"]["provenance"]["params"]["scene"]
    assert scene["num_people"] == suite_scene("standard", "s09_crossing_at_cut").num_people == 2
