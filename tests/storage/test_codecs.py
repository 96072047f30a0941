import dataclasses

import numpy as np

from storage.codecs import decode, encode
from storage.keys import artifact_key
from storage.store import ArtifactStore
from multithumbs.types import CameraTrajectory, GroundTruth, Shots, WorldResult


def _equal(a, b):
    for f in dataclasses.fields(a):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if isinstance(x, np.ndarray):
            np.testing.assert_array_equal(x, y)
        elif dataclasses.is_dataclass(x):
            _equal(x, y)
        elif isinstance(x, dict) and x and all(isinstance(v, np.ndarray) for v in x.values()):
            assert x.keys() == y.keys()
            for k in x:
                np.testing.assert_array_equal(x[k], y[k])
        else:
            assert x == y, f.name


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
