"""The dataset, evaluation and benchmark flows on tiny synthetic videos."""

import dataclasses
import json

import pytest

from multithumbs.errors import InputError
from multithumbs.synth.scene import config_to_json
from tests.flows.conftest import TINY


def _items(n):
    return [{"name": f"v{i}", "scene": config_to_json(dataclasses.replace(TINY, name=f"v{i}", seed=41 + i))}
            for i in range(n)]


@pytest.mark.parametrize("runner", ["threads", "dask"])
def test_dataset_flow_writes_every_video_and_the_table(prefect, tmp_path, runner):
    from flows.dataset import reconstruct_dataset
    from storage.store import ArtifactStore

    rows = reconstruct_dataset(_items(2), str(tmp_path / "out"), str(tmp_path / "store"), runner=runner, workers=2)
    assert [r["video"] for r in rows] == ["v0", "v1"]
    for name in ("v0", "v1"):
        assert (tmp_path / "out" / name / "result.npz").stat().st_size > 0
        assert json.loads((tmp_path / "out" / name / "metrics.json").read_text())["ids"] == 0
    assert json.loads((tmp_path / "out" / "results.json").read_text())[1]["video"] == "v1"
    assert (tmp_path / "out" / "results.md").read_text().count("\n") == 4
    store = ArtifactStore(tmp_path / "store")
    assert sorted(store.record(k)["stage"] for k in store.keys()).count("post") == 2


def test_dataset_flow_rejects_bad_items(prefect, tmp_path):
    from flows.dataset import reconstruct_dataset

    with pytest.raises(InputError, match="no videos"):
        reconstruct_dataset([], str(tmp_path), str(tmp_path / "store"))
    with pytest.raises(InputError, match="unique"):
        reconstruct_dataset(_items(1) * 2, str(tmp_path), str(tmp_path / "store"))
    with pytest.raises(InputError, match="task runner 'ray'"):
        reconstruct_dataset(_items(1), str(tmp_path), str(tmp_path / "store"), runner="ray")


def test_evaluate_flow_scores_ground_truth_as_perfect(prefect, tmp_path):
    from flows.evaluate import evaluate
    from multithumbs.body.model import load_body_model
    from multithumbs.synth.files import write_synthetic
    from multithumbs.synth.scene import synthesize

    write_synthetic(tmp_path, synthesize(TINY, load_body_model()))
    gt = str(tmp_path / "ground_truth.npz")
    metrics = evaluate(gt, gt)
    assert metrics["w_mpjpe"] == pytest.approx(0, abs=1e-6) and metrics["ids"] == 0


def test_benchmark_flow_shares_stages_between_variants(prefect, tmp_path):
    from flows.benchmark import benchmark
    from storage.store import ArtifactStore

    variants = ["full", "no_post", "distance_only", "no_align"]
    summary = benchmark(variants=variants, store_url=str(tmp_path / "store"), out_dir=str(tmp_path / "bench"),
                        scene_configs=[config_to_json(TINY)])
    assert set(summary) == set(variants)
    assert summary["full"]["w_mpjpe"]["per_scene"].keys() == {"tiny"}
    bench = json.loads((tmp_path / "bench" / "bench.json").read_text())
    assert bench["no_post"]["ids"]["mean"] == 0 and bench["no_post"]["ids_total"]["total"] == 0
    assert bench["full"]["ate_alignment"]["per_scene"]["tiny"] in ("sim3_camera_centres", "sim3_people_joints")
    assert "w_mpjpe_track" in (tmp_path / "bench" / "bench.md").read_text()
    stages = [ArtifactStore(tmp_path / "store").record(k)["stage"] for k in ArtifactStore(tmp_path / "store").keys()]
    # full, no_post and distance_only share one alignment; no_align has its own.
    assert stages.count("align") == 2 and stages.count("propagate") == 2


def test_dataset_flow_over_a_fixture_benchmark(prefect, tmp_path):
    """A real-data benchmark (an EgoHumans-layout fixture) built from a spec and run through the real flow."""
    from flows.dataset import benchmark_items, reconstruct_dataset
    from multithumbs.body.model import load_body_model
    from tests.datasets.fixtures import make_egohumans

    root = tmp_path / "egohumans"
    make_egohumans(root, load_body_model(), num_frames=8)
    spec = tmp_path / "clip.json"
    spec.write_text(json.dumps({"name": "eh", "dataset": "egohumans", "sequence": "01_tagging/001_tagging",
                                "cameras": ["cam01", "cam02"], "cuts": [4], "num_frames": 8}))
    items = benchmark_items([str(spec)], str(root), str(tmp_path / "clips"))
    assert items[0]["cuts"] == [4] and items[0]["perception"].startswith("oracle:")
    rows = reconstruct_dataset(items, str(tmp_path / "runs"), str(tmp_path / "store"))
    assert [r["video"] for r in rows] == ["eh"] and rows[0]["backends"]["perception"] == "oracle"
    assert rows[0]["w_mpjpe"] is not None
    table = (tmp_path / "runs" / "results.md").read_text().splitlines()
    assert table[0].startswith("| video | w_mpjpe") and table[2].startswith("| eh |")
    assert (tmp_path / "runs" / "eh" / "report.md").exists()
    # The scheduled form (a deployment's flow) rebuilds nothing and recomputes nothing.
    from flows.dataset import dataset_benchmark
    from storage.store import ArtifactStore

    keys = set(ArtifactStore(tmp_path / "store").keys())
    again = dataset_benchmark([str(spec)], str(root), str(tmp_path), store_url=str(tmp_path / "store"))
    assert again[0]["w_mpjpe"] == pytest.approx(rows[0]["w_mpjpe"])
    assert set(ArtifactStore(tmp_path / "store").keys()) == keys
