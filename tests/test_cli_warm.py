"""`multithumbs demo` run again with the same arguments, as a user runs it: every stage (the evaluation
included) is served from the store through the flow, the outputs are the same bytes, and the process
imports neither torch nor the method, the evaluation or the pictures' libraries (~3 s instead of ~40 s on
two cores: benchmarks/cli_second_run.py)."""

import hashlib
import json
import os
import subprocess
import sys

from flows import local_api

# Runs before the CLI and reports, as its last line on stderr, the modules the command imported (the CLI
# ends with os._exit after the atexit handlers).
PRELUDE = """
import atexit, json, sys
atexit.register(lambda: print("MODULES " + json.dumps(sorted(sys.modules)), file=sys.stderr, flush=True))
sys.argv = ["multithumbs", *sys.argv[1:]]
from multithumbs.cli import main
main()
"""
HEAVY = {"torch", "smplx", "roma", "scipy", "cv2", "matplotlib", "trimesh", "pygltflib", "rerun", "zarr",
         "multithumbs.pipeline", "multithumbs.metrics.evaluate", "multithumbs.body.model", "multithumbs.viz.outputs"}


def _demo(*args, env):
    return subprocess.run([sys.executable, "-c", PRELUDE, "demo", *map(str, args)], capture_output=True,
                          text=True, env=env, timeout=900)


def _digests(folder):
    return {p.relative_to(folder).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file() and "store" not in p.relative_to(folder).parts}


def test_a_second_demo_is_served_from_the_store_and_imports_no_torch(tmp_path):
    from storage.store import ArtifactStore

    cache, out = tmp_path / "cache", tmp_path / "demo"
    env = {**os.environ, "MULTITHUMBS_CACHE": str(cache), "MULTITHUMBS_API_LINGER": "120"}
    env.pop("PREFECT_API_URL", None)
    env.pop("PREFECT_HOME", None)
    try:
        cold = _demo("--out", out, env=env)
        assert cold.returncode == 0, cold.stderr[-3000:]
        store = ArtifactStore(out / "store")
        created = {k: store.record(k)["created"] for k in store.keys()}
        assert "evaluate" in {store.record(k)["stage"] for k in created}
        files = _digests(out)
        assert {"result.npz", "metrics.json", "report.md", "overlay.mp4", "scene.glb"} <= set(files)

        warm = _demo("--out", out, "--overwrite", env=env)
        assert warm.returncode == 0, warm.stderr[-3000:]
        modules = set(json.loads(warm.stderr.strip().splitlines()[-1].removeprefix("MODULES ")))
        assert "flows.reconstruct" in modules and "prefect" in modules  # it did go through the flow
        assert not {m for m in modules if m in HEAVY or m.split(".")[0] in HEAVY}, sorted(modules & HEAVY)
        assert {k: store.record(k)["created"] for k in store.keys()} == created  # nothing computed or written
        assert _digests(out) == files
        assert warm.stdout.split("SIMULATED")[0] == cold.stdout.split("SIMULATED")[0]  # the same metrics table
    finally:
        local_api.stop_kept(cache / "prefect")
