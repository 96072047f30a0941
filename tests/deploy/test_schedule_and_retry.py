"""On a Prefect server and a process worker (loopback): a deployment's interval schedule makes the server's
scheduler create runs that the worker completes (it did not with SQLAlchemy 2.1: the pin in pyproject.toml);
and a run that failed part-way, retried the way the dashboard's Retry button does it, resumes from the store's
committed artifacts and computes only what is missing."""

from __future__ import annotations

import os
import time

import pytest

from tests.deploy.stack import REPO, Stack

FLOWS = '''
from pathlib import Path

from prefect import flow, task


@flow(name="tick")
def tick(path: str) -> None:
    with open(path, "a") as fh:
        fh.write("tick\\n")


@task
def gate(marker: str) -> None:
    """Fails while the marker file exists: a task that raises part-way through the flow."""
    if Path(marker).exists():
        raise RuntimeError(f"injected failure ({marker} exists)")


@flow(name="resumable")
def resumable(scene: dict, store_url: str, marker: str) -> str:
    from flows.method import run_method
    from tasks.inputs import simulate_inputs
    from tasks.method import method_params

    refs = simulate_inputs(store_url, scene)
    gate(marker)
    (method_refs,) = run_method(store_url, [(refs, method_params("full"))])
    return method_refs["result"].key
'''

PREFECT_YAML = '''
name: tests
prefect-version: 3.8.8
build: null
push: null
pull:
  - prefect.deployments.steps.set_working_directory:
      directory: "{work}"
deployments:
  - name: every-5s
    entrypoint: test_flows.py:tick
    parameters: {{path: "{work}/ticks.txt"}}
    schedules:
      - interval: 5
    work_pool: {{name: test-pool}}
  - name: once
    entrypoint: test_flows.py:resumable
    work_pool: {{name: test-pool}}
'''


@pytest.fixture(scope="module")
def stack(tmp_path_factory):
    work = tmp_path_factory.mktemp("deployments")
    # The scheduler's loops and the worker's polling every 2-5 s instead of 10-60 s; the flows import this
    # checkout's code (not another install of the package).
    pythonpath = os.pathsep.join(filter(None, [str(REPO), os.environ.get("PYTHONPATH")]))
    stack = Stack(work, PREFECT_SERVER_SERVICES_SCHEDULER_LOOP_SECONDS="5",
                  PREFECT_SERVER_SERVICES_SCHEDULER_RECENT_DEPLOYMENTS_LOOP_SECONDS="2",
                  PREFECT_WORKER_QUERY_SECONDS="2", PYTHONPATH=pythonpath)
    (work / "test_flows.py").write_text(FLOWS)
    (work / "prefect.yaml").write_text(PREFECT_YAML.format(work=work))
    try:
        stack.start_server()
        stack.prefect("work-pool", "create", "test-pool", "--type", "process")
        stack.prefect("--no-prompt", "deploy", "--prefect-file", str(work / "prefect.yaml"), "--all", cwd=work)
        stack.start_worker("test-pool")
        stack.work = work
        yield stack
    finally:
        stack.close()


def _deployment_id(stack: Stack, name: str) -> str:
    return stack.api("GET", f"/deployments/name/{name}")["id"]


def _wait(predicate, timeout: float, what: str, stack: Stack):
    deadline = time.time() + timeout
    while True:
        value = predicate()
        if value:
            return value
        if time.time() > deadline:
            logs = "\n".join(f"--- {p.name}\n{p.read_text()[-3000:]}" for p in sorted(stack.logs.glob("*.log")))
            raise AssertionError(f"{what}: not within {timeout:.0f} s\n{logs}")
        time.sleep(1)


@pytest.mark.timeout(300)
def test_an_interval_schedule_creates_runs_that_a_worker_completes(stack):
    deployment = _deployment_id(stack, "tick/every-5s")

    def completed_scheduled_run():
        runs = stack.flow_runs(deployment)
        return [r for r in runs if r["auto_scheduled"] and r["state_type"] == "COMPLETED"]

    _wait(completed_scheduled_run, 240, "a scheduled run completed by the worker", stack)
    assert (stack.work / "ticks.txt").read_text().startswith("tick")
    assert "Can't evaluate bulk DML" not in (stack.logs / "server.log").read_text()


@pytest.mark.timeout(600)
def test_a_failed_run_retried_like_the_dashboard_resumes_from_the_store(stack, tmp_path):
    from storage.store import ArtifactStore

    store_url, marker = str(tmp_path / "store"), tmp_path / "fail"
    marker.write_text("fail once")
    scene = {"name": "tiny", "num_people": 2, "num_shots": 2, "num_frames": 10, "seed": 41,
             "image_size": [180, 320], "cut_angle_deg": 30}
    run = stack.api("POST", f"/deployments/{_deployment_id(stack, 'resumable/once')}/create_flow_run",
                    {"parameters": {"scene": scene, "store_url": store_url, "marker": str(marker)}})

    def state():
        return stack.api("GET", f"/flow_runs/{run['id']}")["state_type"]

    _wait(lambda: state() in ("FAILED", "CRASHED", "COMPLETED"), 400, "the first attempt to end", stack)
    assert state() == "FAILED"
    store = ArtifactStore(store_url)
    first = {k: store.record(k) for k in store.keys()}
    assert {r["stage"] for r in first.values()} == {"simulate_inputs"}  # committed before the failing task

    marker.unlink()
    # What the dashboard's Retry button sends (Prefect 3.8 UI: setFlowRunState, force false).
    stack.api("POST", f"/flow_runs/{run['id']}/set_state",
              {"state": {"type": "SCHEDULED", "name": "AwaitingRetry", "message": "Retry from the UI"}, "force": False})
    _wait(lambda: state() in ("COMPLETED", "FAILED", "CRASHED") and stack.api(
        "GET", f"/flow_runs/{run['id']}")["run_count"] >= 2, 400, "the retried run to end", stack)
    assert state() == "COMPLETED"
    after = {k: store.record(k) for k in store.keys()}
    assert {r["stage"] for r in after.values()} == {"simulate_inputs", "align", "propagate", "reid", "post"}
    for key, record in first.items():  # served from the store, not written again
        assert after[key]["created"] == record["created"], record["stage"]
