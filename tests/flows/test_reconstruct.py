"""A real end-to-end flow: the synthetic demo through Prefect (ephemeral API), then again from the store."""

import json
import os
import time

import pytest

from multithumbs.synth.scene import SceneConfig, config_to_json

TINY = SceneConfig(name="tiny", num_people=2, num_shots=2, num_frames=10, seed=41, image_size=(180, 320),
                   cut_angle_deg=30)


@pytest.fixture(scope="module")
def prefect(tmp_path_factory):
    os.environ.setdefault("PREFECT_HOME", str(tmp_path_factory.mktemp("prefect")))
    os.environ.setdefault("PREFECT_SERVER_EPHEMERAL_STARTUP_TIMEOUT_SECONDS", "90")
    from prefect.testing.utilities import prefect_test_harness

    with prefect_test_harness(server_startup_timeout=120):
        yield


def test_flow_reconstructs_then_serves_everything_from_the_store(prefect, tmp_path):
    from flows.reconstruct import reconstruct_synthetic
    from storage.store import ArtifactStore

    out, store_url = tmp_path / "out", str(tmp_path / "store")
    out.mkdir()
    start = time.perf_counter()
    metrics = reconstruct_synthetic(config_to_json(TINY), str(out), store_url)
    first = time.perf_counter() - start
    for name in ("video.mp4", "ground_truth.npz", "contact_sheet.png", "result.npz", "metrics.json"):
        assert (out / name).stat().st_size > 0
    assert metrics["ids"] == 0 and metrics["w_mpjpe"] < 300
    assert json.loads((out / "metrics.json").read_text())["mpjpe"] == pytest.approx(metrics["mpjpe"])
    store = ArtifactStore(store_url)
    created = {k: store.record(k)["created"] for k in store.keys()}
    assert {store.record(k)["stage"] for k in created} == {"simulate_inputs", "align", "propagate", "reid", "post"}

    start = time.perf_counter()
    again = reconstruct_synthetic(config_to_json(TINY), str(out), store_url)
    second = time.perf_counter() - start
    # Nothing was computed again: the same artifacts, untouched, and the same numbers.
    assert {k: store.record(k)["created"] for k in store.keys()} == created
    assert again["w_mpjpe"] == pytest.approx(metrics["w_mpjpe"])
    assert second < first / 3, (first, second)


def test_changing_a_reid_parameter_recomputes_reid_and_what_follows_only(prefect, tmp_path):
    from flows.reconstruct import reconstruct_synthetic
    from storage.store import ArtifactStore

    out, store_url = tmp_path / "out", str(tmp_path / "store")
    out.mkdir()
    reconstruct_synthetic(config_to_json(TINY), str(out), store_url)
    store = ArtifactStore(store_url)
    before = {k: store.record(k)["stage"] for k in store.keys()}
    reconstruct_synthetic(config_to_json(TINY), str(out), store_url, method={"reid": {"max_distance": 0.8}})
    new = {k: store.record(k)["stage"] for k in store.keys() if k not in before}
    assert sorted(new.values()) == ["post", "reid"]
