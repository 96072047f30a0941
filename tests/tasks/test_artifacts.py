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


def test_prefect_caches_a_ref_only_while_the_store_holds_its_artifact(tmp_path):
    """Prefect's cache key names the artifact in its store; it is withheld (the task runs and recomputes)
    only when the store lacks the artifact but Prefect has a ref to it cached."""
    from types import SimpleNamespace

    from tasks.artifacts import prefect_cache_key

    cached = set()
    context = SimpleNamespace(result_store=SimpleNamespace(exists=lambda key: key in cached))
    a, b = str(tmp_path / "a"), str(tmp_path / "b")
    ref = cached_stage("shots", _shots, a, {"video": "abc"}, {})
    key_a = prefect_cache_key(context, ref.key, a)
    assert key_a.startswith(ref.key) and key_a != prefect_cache_key(context, ref.key, b)  # one key per store
    assert prefect_cache_key(context, ref.key, b) is not None  # b computes it now and caches its ref
    cached.add(key_a)
    assert prefect_cache_key(context, ref.key, a) == key_a  # served from Prefect's cache
    open_store(a).delete(ref.key)
    assert prefect_cache_key(context, ref.key, a) is None  # deleted from the store: computed again
    assert prefect_cache_key(SimpleNamespace(), ref.key, a) is None  # no result store to ask: cache nothing
