import json

import numpy as np
import pytest

from multithumbs.errors import InputError
from multithumbs.io import load_ground_truth, load_result, save_ground_truth, save_result
from multithumbs.synth.scene import SceneConfig, synthesize


@pytest.fixture(scope="module")
def truth(body):
    return synthesize(SceneConfig(num_people=2, num_frames=6, seed=2, image_size=(90, 160)), body).truth


def test_ground_truth_round_trip_and_is_a_valid_result(tmp_path, truth):
    path = save_ground_truth(tmp_path / "gt.npz", truth, {"instance": np.zeros((6, 90, 160), np.int8)})
    loaded, extras = load_ground_truth(path)
    for name, value in truth.world.arrays().items():
        np.testing.assert_array_equal(getattr(loaded.world, name), value)
    assert loaded.metadata == json.loads(json.dumps(truth.metadata)) and extras["instance"].shape == (6, 90, 160)
    as_result = load_result(path)
    np.testing.assert_array_equal(as_result.transl, truth.world.transl)
    assert (path.stat().st_mode & 0o777) != 0o600  # usual permissions, not the temp file's


def test_result_round_trip_keeps_diagnostics(tmp_path, truth):
    world = truth.world
    import dataclasses
    result = dataclasses.replace(world, diagnostics={"loss": np.arange(3.0)})
    loaded = load_result(save_result(tmp_path / "r.npz", result))
    np.testing.assert_array_equal(loaded.diagnostics["loss"], [0, 1, 2])
    with pytest.raises(InputError, match="not a ground-truth file"):
        load_ground_truth(tmp_path / "r.npz")


def test_bad_files_are_named(tmp_path):
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"not a zip")
    with pytest.raises(InputError, match="bad.npz"):
        load_result(bad)
    np.savez(tmp_path / "other.npz", x=np.zeros(3))
    with pytest.raises(InputError, match="not a Multi-THuMBS"):
        load_result(tmp_path / "other.npz")
