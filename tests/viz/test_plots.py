import json
import xml.etree.ElementTree as ET

import cv2
import numpy as np
import pytest

from multithumbs.errors import InputError
from multithumbs.export.posed import posed_joints
from multithumbs.viz.plots import benchmark_table, result_to_truth, write_benchmark_plots, write_trajectory_plot
from tests.export.conftest import rigid_copy, tilted_rotation


def test_trajectory_plot_files(small_scene, body, tmp_path):
    world = small_scene.world
    joints = posed_joints(world, body)
    files = write_trajectory_plot(tmp_path / "trajectory", world, joints, title="scene")
    image = cv2.imread(str(files["png"]))
    assert image is not None and image.shape[0] > 300 and image.shape[1] > 300
    assert ET.parse(files["svg"]).getroot().tag.endswith("svg")
    with_truth = write_trajectory_plot(tmp_path / "with_truth", world, joints, small_scene.truth, joints)
    assert cv2.imread(str(with_truth["png"])) is not None
    assert sorted(p.name for p in tmp_path.iterdir()) == ["trajectory.png", "trajectory.svg", "with_truth.png",
                                                          "with_truth.svg"]


def test_result_is_aligned_to_the_truth(small_scene, body, tmp_path):
    """A result in another world frame is mapped back onto the truth for the dashed comparison."""
    world = small_scene.world
    rotation, translation = tilted_rotation(), np.array([2.0, -1.0, 0.5])
    moved = rigid_copy(world, body, rotation, translation)
    true_joints = posed_joints(world, body)
    sim = result_to_truth(moved, posed_joints(moved, body), small_scene.truth, true_joints)
    assert float(sim.scale) == pytest.approx(1.0, abs=1e-6)
    np.testing.assert_allclose(sim.rotation.numpy(), rotation.T, atol=1e-6)
    files = write_trajectory_plot(tmp_path / "moved", moved, posed_joints(moved, body), small_scene.truth, true_joints)
    assert cv2.imread(str(files["png"])) is not None


def bench_summary():
    scenes = ["s01", "s02", "s03"]
    return {
        "full": {"w_mpjpe": {"per_scene": dict(zip(scenes, [100.0, 120.0, None])), "mean": 110.0},
                 "ids": {"per_scene": dict(zip(scenes, [0, 1, 0])), "mean": 0.33}},
        "no_align": {"w_mpjpe": {"per_scene": dict(zip(scenes, [300.0, 250.0, 280.0])), "mean": 276.7},
                     "ids": {"per_scene": dict(zip(scenes, [2, 1, 3])), "mean": 2.0}},
        "_meta": {"suite": "standard", "seconds": 12.0},
    }


def test_benchmark_plots(tmp_path):
    summary = json.loads(json.dumps(bench_summary()))  # as `multithumbs bench --json` prints it
    variants, metrics, values = benchmark_table(summary)
    assert variants == ["full", "no_align"] and metrics == ["w_mpjpe", "ids"]
    assert np.isnan(values["w_mpjpe"]["full"]["s03"])
    files = write_benchmark_plots(tmp_path, summary)
    assert sorted(files) == ["ids.png", "ids.svg", "w_mpjpe.png", "w_mpjpe.svg"]
    assert cv2.imread(str(files["w_mpjpe.png"])) is not None
    assert ET.parse(files["ids.svg"]).getroot().tag.endswith("svg")


def test_benchmark_errors(tmp_path):
    with pytest.raises(InputError, match="no variant"):
        benchmark_table({"_meta": {}})
    with pytest.raises(InputError, match="per_scene"):
        benchmark_table({"full": {"w_mpjpe": 3.0}})
    with pytest.raises(InputError, match="keyed by variant"):
        benchmark_table([1, 2])
    with pytest.raises(InputError, match="metric 'nope'"):
        write_benchmark_plots(tmp_path, bench_summary(), ["nope"])
