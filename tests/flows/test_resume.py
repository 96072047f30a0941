"""A run killed with SIGKILL in the middle of alignment resumes to the same results, leaving nothing half-written."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from multithumbs.synth.scene import config_to_json
from tests.flows.conftest import TINY

REPO = Path(__file__).resolve().parents[2]
CHILD = """
import json, sys
from flows.reconstruct import reconstruct_synthetic
reconstruct_synthetic(json.loads(sys.argv[1]), sys.argv[2], sys.argv[3])
"""


def _stages(store) -> list[str]:
    return sorted(store.record(k)["stage"] for k in store.keys())


def test_sigkill_during_alignment_then_resume_equals_uninterrupted(prefect, tmp_path):
    from flows.reconstruct import reconstruct_synthetic
    from multithumbs.io import load_result
    from storage.store import ArtifactStore

    scene = config_to_json(TINY)
    store_url, out = tmp_path / "store", tmp_path / "killed"
    out.mkdir()
    env = {**os.environ, "PREFECT_HOME": str(tmp_path / "child_prefect"), "PREFECT_SERVER_ANALYTICS_ENABLED": "false",
           "PREFECT_SERVER_EPHEMERAL_STARTUP_TIMEOUT_SECONDS": "120", "PREFECT_LOGGING_LEVEL": "WARNING"}
    env.pop("PREFECT_API_URL", None)
    child = subprocess.Popen([sys.executable, "-c", CHILD, json.dumps(scene), str(out), str(store_url)], cwd=REPO,
                             env=env, start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    store = ArtifactStore(store_url)
    n_inputs = 2 + 2 * TINY.num_shots + (TINY.num_shots - 1)  # truth, shots, tracks, trajectories, spaces
    deadline = time.time() + 300
    try:
        while _stages(store).count("simulate_inputs") < n_inputs:
            assert child.poll() is None, "the run ended before alignment"
            assert time.time() < deadline, "inputs never appeared"
            time.sleep(0.2)
        time.sleep(1.0)  # alignment (2,500 AdamW iterations) is now running
        assert "align" not in _stages(store), "alignment finished before the kill: the test needs a longer one"
    finally:
        os.killpg(child.pid, signal.SIGKILL)
        child.wait(timeout=30)
    assert child.returncode == -signal.SIGKILL
    # Nothing half-written is visible: every committed artifact reads with its checksums, only inputs exist.
    assert set(_stages(store)) == {"simulate_inputs"}
    for key in store.keys():
        store.read(key)
    assert not (out / "result.npz").exists()
    store.gc(keep=store.keys(), stale_seconds=0)  # sweeps whatever the killed writer left in tmp/
    assert not any(Path(store.root, "tmp").iterdir())

    resumed = reconstruct_synthetic(scene, str(out), str(store_url))
    fresh_out = tmp_path / "uninterrupted"
    fresh_out.mkdir()
    uninterrupted = reconstruct_synthetic(scene, str(fresh_out), str(tmp_path / "fresh_store"))
    # Bitwise equal: every stage computes with one fixed thread count (multithumbs.determinism), so the
    # inputs the killed child wrote and the ones computed here, and everything after them, are the same bytes.
    assert resumed.keys() == uninterrupted.keys() and resumed["ids"] == uninterrupted["ids"]
    for key, value in resumed.items():
        if isinstance(value, float):
            assert value == uninterrupted[key] or (np.isnan(value) and np.isnan(uninterrupted[key])), key
    a, b = load_result(out / "result.npz"), load_result(fresh_out / "result.npz")
    for name in ("global_orient", "body_pose", "betas", "transl", "R", "t", "id_map"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
