"""bench --from-pixels inputs kept in the artifact store: the second run reads them, a half-written entry is
computed again, and a change of what the inputs depend on misses the cache."""

import numpy as np
import pytest

from multithumbs import bench
from multithumbs.method.align import AlignConfig
from multithumbs.method.post import PostConfig
from multithumbs.pipeline import MethodConfig
from multithumbs.synth.scene import SceneConfig
from tasks.bench_inputs import StoreInputCache

FAST = MethodConfig(align=AlignConfig(iterations=(0, 30, 60)), post=PostConfig(iterations=30))
SCENE = SceneConfig(num_people=2, num_shots=2, num_frames=12, seed=5, image_size=(180, 320), cut_angle_deg=30)


def test_second_run_reads_the_kept_inputs_and_scores_the_same(tmp_path, monkeypatch):
    cache = StoreInputCache(str(tmp_path / "store"))
    first = bench.run_scene(SCENE, ["full"], FAST, inputs="pixels", pixel_stages=("camera_tracking",),
                            input_cache=cache)
    assert "inputs" not in first.backends

    def not_again(*args, **kwargs):
        raise AssertionError("pixel inputs computed again")

    monkeypatch.setattr(bench, "pixel_inputs", not_again)
    second = bench.run_scene(SCENE, ["full"], FAST, inputs="pixels", pixel_stages=("camera_tracking",),
                             input_cache=cache)
    assert second.backends.pop("inputs") == "kept from an earlier run"
    assert second.backends == first.backends
    for name, value in second.metrics["full"].items():  # the same inputs, bit for bit: the same scores
        np.testing.assert_array_equal(value, first.metrics["full"][name], err_msg=name)
    assert second.stage_seconds.keys() == first.stage_seconds.keys()
    with pytest.raises(AssertionError, match="computed again"):  # other stages: another entry
        bench.run_scene(SCENE, ["full"], FAST, inputs="pixels", pixel_stages=("shared_space",), input_cache=cache)


def test_an_entry_without_its_manifest_is_not_read(tmp_path):
    cache = StoreInputCache(str(tmp_path / "store"))
    params = {"scene": "x", "stages": ["shots"], "withhold_focal": False, "seed": 0}
    from multithumbs.types import Shots

    shots = Shots(np.array([4]), 24.0, 8, np.zeros(8), "given")
    cache.save(params, (shots, [], [], [], {"shots": "given"}, {"shots": float("nan")}))
    shots_back, tracks, trajectories, spaces, backends, seconds = cache.load(params)
    np.testing.assert_array_equal(shots_back.cut_frames, [4])
    assert (tracks, trajectories, spaces, backends) == ([], [], [], {"shots": "given"}) and np.isnan(seconds["shots"])
    assert cache.load({**params, "seed": 1}) is None  # another key while this entry is there
    from tasks.artifacts import open_store

    manifest, _ = cache._keys(params)
    open_store(cache.url).delete(manifest)  # as if killed before the manifest was committed
    assert cache.load(params) is None
