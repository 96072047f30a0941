"""A real deployment round trip: a Prefect server and a process worker on loopback, `prefect deploy` from
deploy/prefect.yaml, `prefect deployment run`, the flow's artifacts checked; everything started is stopped."""

from __future__ import annotations

import json

from tests.deploy.stack import Stack


def test_deploy_run_and_check_artifacts(tmp_path):
    stack = Stack(tmp_path)
    prefect = stack.prefect
    try:
        stack.start_server()
        prefect("work-pool", "create", "multithumbs-process", "--type", "process")
        prefect("--no-prompt", "deploy", "--prefect-file", "deploy/prefect.yaml", "--name", "synthetic-video",
                "--name", "nightly-standard", "--name", "standard-suite", "--name", "egohumans-weekly")
        for name in ("reconstruct-synthetic/synthetic-video", "reconstruct-dataset/nightly-standard",
                     "benchmark/standard-suite"):
            assert "multithumbs-process" in prefect("deployment", "inspect", name)
        assert "0 2 * * *" in prefect("deployment", "inspect", "reconstruct-dataset/nightly-standard")
        assert "0 3 * * 0" in prefect("deployment", "inspect", "dataset-benchmark/egohumans-weekly")
        stack.start_worker("multithumbs-process")

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
        assert stages == {"simulate_inputs", "align", "propagate", "reid", "post", "evaluate"}
    finally:
        stack.close()
