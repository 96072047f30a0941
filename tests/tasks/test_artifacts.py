"""The store-backed stage wrapper (unit level: no Prefect run)."""

from pathlib import Path

import numpy as np

from multithumbs.types import Shots
from tasks.artifacts import cached_stage, load, open_store


def _shots():
    return Shots(np.array([5]), 30.0, 10, np.linspace(0, 1, 10), "test")


def test_cached_stage_computes_once_and_recomputes_a_corrupt_artifact(tmp_path):
    url, calls = str(tmp_path / "store"), []

    def compute():
        calls.append(1)
        return _shots()

    ref = cached_stage("shots", compute, url, {"video": "abc"}, {})
    assert cached_stage("shots", compute, url, {"video": "abc"}, {}) == ref and len(calls) == 1
    chunk = max((p for p in (Path(url) / "artifacts" / ref.key / "scores").rglob("*") if p.is_file()),
                key=lambda p: p.stat().st_size)
    chunk.write_bytes(chunk.read_bytes()[: chunk.stat().st_size // 2])  # a truncated chunk
    again = cached_stage("shots", compute, url, {"video": "abc"}, {})
    assert again == ref and len(calls) == 2
    np.testing.assert_array_equal(load(again).scores, _shots().scores)
    assert open_store(url).keys() == [ref.key]


def test_a_changed_parameter_is_a_new_artifact(tmp_path):
    url = str(tmp_path / "store")
    a = cached_stage("shots", _shots, url, {"video": "abc"}, {})
    b = cached_stage("shots", _shots, url, {"video": "abd"}, {})
    assert a.key != b.key and sorted(open_store(url).keys()) == sorted([a.key, b.key])
