import json

import bvhio
import cv2
import numpy as np
import pycolmap
import pytest
import rerun.chunk as rc
import trimesh

from multithumbs.errors import InputError
from multithumbs.viz.outputs import OUTPUT_KINDS, planned_files, write_video_outputs


@pytest.fixture(scope="module")
def exported(small_scene, body, tmp_path_factory):
    out = tmp_path_factory.mktemp("outputs")
    points = [np.random.default_rng(0).uniform([-2, -2, 0], [2, 2, 2], (30, 3))]
    stages = []
    written = write_video_outputs(out, small_scene.world, small_scene.video_path, small_scene.truth,
                                  metrics={"w_mpjpe": 0.0, "ids": 0},
                                  run_info={"backends": {"perception": "simulated"}, "timings": {"align": 1.0}},
                                  scene_points=points, body=body, progress=stages.append)
    return out, written, stages


def test_every_file_opens_with_its_reader(exported, small_scene):
    out, written, stages = exported
    world = small_scene.world
    assert set(written) == set(planned_files(world))
    assert stages[0] == "posing" and set(OUTPUT_KINDS) <= set(stages)
    capture = cv2.VideoCapture(str(written["overlay"]))
    assert int(capture.get(cv2.CAP_PROP_FRAME_COUNT)) == world.num_frames
    assert capture.read()[1].shape == (world.image_size[0], 2 * world.image_size[1], 3)
    capture.release()
    assert cv2.imread(str(written["trajectory_png"])) is not None
    with np.load(written["smpl/person_00"]) as data:
        np.testing.assert_allclose(data["transl"], world.transl[0])
    with np.load(written["cameras"]) as data:
        np.testing.assert_allclose(data["R"], world.R)
        np.testing.assert_array_equal(data["world_up"], [0, 0, 1])
    rec = pycolmap.Reconstruction(str(out / "colmap"))
    assert rec.num_images() == world.num_frames and rec.num_points3D() == 30
    assert any(p.color.tolist() != [128, 128, 128] for p in rec.points3D.values())  # sampled from the video
    assert bvhio.readAsBvh(str(written["bvh/person_01"])).FrameCount == world.num_frames
    assert len(trimesh.load(str(written["glb"])).geometry) == 4
    assert rc.RrdReader(str(written["rrd"])).recordings()
    report = written["report"].read_text()
    assert "![Top-down trajectories](trajectory.png)" in report and "| perception | simulated |" in report
    assert "| overlay |" in report  # export timings
    manifest = json.loads(written["manifest"].read_text())
    assert set(manifest["files"]) == {str(p.relative_to(out)) for p in written.values()}
    assert not [p for p in out.rglob(".*")]  # no temporary files left


def test_rewrites_own_files_but_refuses_others(exported, small_scene, body, tmp_path):
    out, written, _ = exported
    again = write_video_outputs(out, small_scene.world, small_scene.video_path, body=body, include=["cameras"])
    assert set(again) == {"cameras", "manifest"}
    manifest = json.loads(again["manifest"].read_text())
    assert "scene.glb" in manifest["files"]  # earlier outputs stay listed
    # A folder holding a user's file of the same name: refused before anything is written.
    (tmp_path / "cameras.npz").write_text("mine")
    with pytest.raises(InputError, match="cameras.npz: already exists"):
        write_video_outputs(tmp_path, small_scene.world, small_scene.video_path, body=body,
                            include=["trajectory", "cameras"])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cameras.npz"]
    assert (tmp_path / "cameras.npz").read_text() == "mine"
    (tmp_path / "outputs.json").write_text("{}")  # a manifest we did not write does not vouch for anything
    with pytest.raises(InputError, match="already exists"):
        write_video_outputs(tmp_path, small_scene.world, small_scene.video_path, body=body, include=["cameras"])
    written = write_video_outputs(tmp_path, small_scene.world, small_scene.video_path, body=body,
                                  include=["cameras"], overwrite=True)
    assert np.load(written["cameras"])["R"].shape == small_scene.world.R.shape


def test_retry_after_a_failure_part_way_replaces_its_own_files(small_scene, body, tmp_path, monkeypatch):
    import multithumbs.export.cameras as cameras

    def broken(*args, **kwargs):
        raise RuntimeError("disk full")

    monkeypatch.setattr(cameras, "write_colmap_text", broken)
    with pytest.raises(RuntimeError, match="disk full"):
        write_video_outputs(tmp_path, small_scene.world, small_scene.video_path, body=body,
                            include=["cameras", "colmap"])
    claimed = json.loads((tmp_path / "outputs.json").read_text())
    assert claimed["complete"] is False and "colmap/images.txt" in claimed["files"]
    assert (tmp_path / "cameras.npz").exists() and not (tmp_path / "colmap").exists()
    monkeypatch.undo()
    written = write_video_outputs(tmp_path, small_scene.world, small_scene.video_path, body=body,
                                  include=["cameras", "colmap"])  # no overwrite needed: its own files
    manifest = json.loads(written["manifest"].read_text())
    assert manifest["complete"] is True
    assert set(manifest["files"]) == {"outputs.json", "cameras.npz", "colmap/cameras.txt", "colmap/images.txt",
                                      "colmap/points3D.txt"}


def test_bad_inputs(small_scene, body, tmp_path):
    world = small_scene.world
    with pytest.raises(InputError, match="no such video"):
        write_video_outputs(tmp_path / "o", world, tmp_path / "none.mp4", body=body)
    with pytest.raises(InputError, match="unknown output kind 'pdf'"):
        write_video_outputs(tmp_path / "o", world, small_scene.video_path, body=body, include=["pdf"])
    with pytest.raises(InputError, match="one array per cut"):
        write_video_outputs(tmp_path / "o", world, small_scene.video_path, body=body, scene_points=[np.zeros((2, 3))] * 3)
    (tmp_path / "file").write_text("x")
    with pytest.raises(InputError, match="not a folder"):
        write_video_outputs(tmp_path / "file", world, small_scene.video_path, body=body, include=["cameras"])
    assert not (tmp_path / "o").exists()
