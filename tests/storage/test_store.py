import multiprocessing
import os

import numpy as np
import pytest

from storage.keys import artifact_key
from storage.store import ArtifactStore, CorruptArtifact


def _arrays(seed=0):
    rng = np.random.default_rng(seed)
    return {"transl": rng.normal(size=(3, 50, 3)), "valid": rng.random((3, 50)) > 0.2,
            "diag/loss": np.arange(10.0), "ids": np.arange(3)}


def test_write_read_round_trip_with_provenance(tmp_path):
    store = ArtifactStore(tmp_path / "store")
    key = artifact_key("align", 1, {"iterations": [1, 2, 3]}, [])
    ref = store.write(key, "align", _arrays(), {"params": {"iterations": [1, 2, 3]}})
    assert ref.key == key and store.exists(key) and store.keys() == [key]
    arrays, attrs = store.read(key)
    for name, value in _arrays().items():
        np.testing.assert_array_equal(arrays[name], value)
        assert arrays[name].dtype == value.dtype
    assert attrs["params"]["iterations"] == [1, 2, 3] and store.record(key)["stage"] == "align"
    assert not list((tmp_path / "store" / "tmp").iterdir())  # nothing half-written left behind


def test_a_truncated_chunk_is_detected(tmp_path):
    store = ArtifactStore(tmp_path)
    key = artifact_key("x", 1, {}, [])
    store.write(key, "x", _arrays(), {})
    chunk = max((p for p in (tmp_path / "artifacts" / key / "transl").rglob("*") if p.is_file()),
                key=lambda p: p.stat().st_size)
    chunk.write_bytes(chunk.read_bytes()[: chunk.stat().st_size // 2])
    with pytest.raises(CorruptArtifact):
        store.read(key)
    store.delete(key)  # the documented recovery: delete, recompute, write again
    store.write(key, "x", _arrays(), {})
    np.testing.assert_array_equal(store.read(key)[0]["transl"], _arrays()["transl"])


def test_garbage_collection_keeps_what_is_referenced(tmp_path):
    store = ArtifactStore(tmp_path)
    keys = [artifact_key("s", 1, {"i": i}, []) for i in range(3)]
    for k in keys:
        store.write(k, "s", {"a": np.zeros(3)}, {})
    (tmp_path / "artifacts" / ("f" * 64)).mkdir()  # a crashed writer's uncommitted leftovers
    removed = store.gc(keep=[keys[0]])
    assert set(removed) == {keys[1], keys[2], "f" * 64} and store.keys() == [keys[0]]


def _writer(root, key, seed, barrier):
    barrier.wait()
    ArtifactStore(root).write(key, "race", _arrays(seed), {"writer": os.getpid()})


def test_two_processes_writing_one_artifact_leave_one_good_result(tmp_path):
    key = artifact_key("race", 1, {}, [])
    ctx = multiprocessing.get_context("spawn")
    barrier = ctx.Barrier(2)
    procs = [ctx.Process(target=_writer, args=(str(tmp_path), key, 0, barrier)) for _ in range(2)]
    for p in procs:
        p.start()
    for p in procs:
        p.join(60)
        assert p.exitcode == 0
    store = ArtifactStore(tmp_path)
    arrays, _ = store.read(key)
    np.testing.assert_array_equal(arrays["transl"], _arrays(0)["transl"])
    assert store.keys() == [key] and not list((tmp_path / "tmp").iterdir())
