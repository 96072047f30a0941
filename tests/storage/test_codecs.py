import dataclasses

import numpy as np

from storage.codecs import decode, encode
from storage.keys import artifact_key
from storage.store import ArtifactStore
from multithumbs.method.reid import Matching
from multithumbs.pipeline import Identities, Placement
from multithumbs.types import CameraTrajectory, GroundTruth, Shots, WorldResult


def _equal(a, b):
    for f in dataclasses.fields(a):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if isinstance(x, np.ndarray):
            np.testing.assert_array_equal(x, y)
        elif dataclasses.is_dataclass(x):
            _equal(x, y)
        elif isinstance(x, tuple) and x and not np.isscalar(x[0]):
            assert len(x) == len(y), f.name
            for u, v in zip(x, y):
                _equal_value(u, v)
        elif isinstance(x, dict) and x and all(isinstance(v, np.ndarray) for v in x.values()):
            assert x.keys() == y.keys()
            for k in x:
                np.testing.assert_array_equal(x[k], y[k])
        else:
            assert x == y, f.name


def _equal_value(x, y):
    if isinstance(x, np.ndarray):
        np.testing.assert_array_equal(x, y)
    else:
        _equal(x, y)


def test_contracts_survive_the_store(tmp_path):
    store = ArtifactStore(tmp_path)
    rng = np.random.default_rng(0)
    T = 6
    items = [
        Shots(np.array([3]), 30.0, T, rng.random(T), "scenedetect:adaptive"),
        CameraTrajectory(1, 3, np.eye(3), np.tile(np.eye(3), (3, 1, 1)), rng.normal(size=(3, 3)),
                         rng.normal(size=(20, 3)), "simulated"),
        WorldResult(np.arange(2), rng.normal(size=(2, T, 3)), rng.normal(size=(2, T, 23, 3)), rng.normal(size=(2, 10)),
                    rng.normal(size=(2, T, 3)), rng.random((2, T)) > 0.3, np.tile(np.eye(3), (T, 1, 1)),
                    np.tile(np.eye(3), (T, 1, 1)), rng.normal(size=(T, 3)), np.array([3]), 30.0, (90, 160),
                    np.array([[0, 5, 0], [1, 7, 0]]), rng.random((2, T, 24, 3)), {"loss": np.arange(4.0)}),
    ]
    items.append(GroundTruth(items[2], rng.random((2, T, 4)), rng.random((2, T)) > 0.5, np.array([0, 0, 0, 1, 1, 1]),
                             {"kind": "synthetic", "config": {"seed": 3}}))
    for i, item in enumerate(items):
        arrays, attrs = encode(item)
        key = artifact_key(type(item).__name__, 1, {"i": i}, [])
        store.write(key, "test", arrays, attrs)
        _equal(decode(*store.read(key)), item)


def test_method_intermediates_survive_the_store(tmp_path):
    """Per-shot arrays of different shapes and per-cut nested contracts (the propagation and re-ID outputs)."""
    store = ArtifactStore(tmp_path)
    rng = np.random.default_rng(1)
    eye = np.tile(np.eye(3), (7, 1, 1))
    placement = Placement(eye, rng.normal(size=(7, 3)), eye, (rng.normal(size=(2, 3, 3)), rng.normal(size=(3, 4, 3))),
                          (rng.normal(size=(2, 3, 3)), rng.normal(size=(3, 4, 3))),
                          (rng.normal(size=(2, 3, 3)), rng.normal(size=(3, 4, 3))), np.array([1.0, np.nan]),
                          np.eye(4)[None])
    matching = Matching(np.array([[0, 1], [1, 0]]), *rng.random((4, 2, 3)))
    ids = Identities((np.array([0, 1]), np.array([1, 0, 2])), (matching,), (np.array([0, 1]),),
                     np.array([[True], [True], [False]]))
    for i, item in enumerate((placement, ids)):
        key = artifact_key("intermediate", 1, {"i": i}, [])
        store.write(key, "test", *encode(item))
        _equal(decode(*store.read(key)), item)
