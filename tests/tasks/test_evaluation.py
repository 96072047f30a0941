"""The evaluation stage: metrics stored under a key of the result, the truth, the options and the body, and
served from the store on a re-run (unit level: the task's function without a Prefect run; the metrics
themselves are tests/metrics')."""

import math
from pathlib import Path

import numpy as np
import pytest

from multithumbs.types import Shots
from storage.store import ArtifactStore
from tasks.artifacts import cached_stage
from tasks.evaluation import evaluate_result


@pytest.fixture
def refs(tmp_path, monkeypatch):
    """Two committed artifacts standing for a result and its truth, and an evaluation that counts its calls."""
    monkeypatch.delenv("MULTITHUMBS_SMPL_MODEL", raising=False)
    url = str(tmp_path / "store")
    shots = lambda n: (lambda: Shots(np.array([5]), 30.0, n, np.zeros(n), "test"))  # noqa: E731
    result, truth = (cached_stage("shots", shots(n), url, {"n": n}, {}) for n in (10, 12))
    calls = []

    def fake_evaluate(predicted, gt, body, **options):
        calls.append(options)
        return {"w_mpjpe": 12.5 + len(calls), "ate": float("nan"), "ids": 0, "options": options,
                "per_cut": np.array([1, 2])}

    import importlib

    # The module (multithumbs.metrics re-exports its function `evaluate` under the module's name).
    monkeypatch.setattr(importlib.import_module("multithumbs.metrics.evaluate"), "evaluate", fake_evaluate)
    monkeypatch.setattr("multithumbs.body.model.load_body_model", lambda path=None: None)
    return url, result, truth, calls


def test_the_metrics_are_computed_once_then_served_from_the_store(refs):
    url, result, truth, calls = refs
    first = evaluate_result.fn(result, truth)
    assert first["w_mpjpe"] == 13.5 and math.isnan(first["ate"]) and first["per_cut"] == [1, 2]
    again = evaluate_result.fn(result, truth)
    assert len(calls) == 1  # not evaluated again
    assert again["w_mpjpe"] == first["w_mpjpe"] and math.isnan(again["ate"]) and list(again) == list(first)
    store = ArtifactStore(url)
    (key,) = [k for k in store.keys() if store.record(k)["stage"] == "evaluate"]
    assert store.record(key)["attributes"]["provenance"]["inputs"] == {"result": result.key, "truth": truth.key}


def test_another_option_truth_or_body_file_scores_again(refs, tmp_path):
    import shutil

    from multithumbs.body.procedural import procedural_model_path

    url, result, truth, calls = refs
    evaluate_result.fn(result, truth)
    evaluate_result.fn(result, truth, options={"chunk": None})
    assert calls == [{}, {"chunk": None}]
    evaluate_result.fn(truth, result)  # the roles swapped: other inputs
    assert len(calls) == 3
    user_file = tmp_path / "my_smpl.npz"
    shutil.copy(procedural_model_path(), user_file)
    evaluate_result.fn(result, truth, str(user_file))
    evaluate_result.fn(result, truth, str(user_file))
    assert len(calls) == 4
    assert sum(ArtifactStore(url).record(k)["stage"] == "evaluate" for k in ArtifactStore(url).keys()) == 4


def test_a_corrupt_evaluation_is_computed_again(refs):
    url, result, truth, calls = refs
    evaluate_result.fn(result, truth)
    store = ArtifactStore(url)
    (key,) = [k for k in store.keys() if store.record(k)["stage"] == "evaluate"]
    chunk = max((p for p in Path(store.root, "artifacts", key).rglob("*") if p.is_file() and p.name != "zarr.json"),
                key=lambda p: p.stat().st_size)
    chunk.write_bytes(b"garbage")
    assert evaluate_result.fn(result, truth)["w_mpjpe"] == 14.5 and len(calls) == 2
