import shutil

import cv2
import numpy as np
import pytest

from multithumbs.datasets.egobody import find_recordings, gendered_bodies, load_egobody
from multithumbs.errors import InputError
from tests.datasets.fixtures import REC, make_egobody


def test_frames_outside_the_valid_range_are_excluded(egobody):
    root, truth = egobody
    seq = load_egobody(root, REC)
    assert truth.frame_ids == [3, 4, 5, 6, 7, 8]
    assert seq.frame_ids.tolist() == [4, 5, 6, 7]  # the CSV's start_frame..end_frame
    assert seq.camera_names == ("master", "sub_1") and seq.people == ("body_idx_0", "body_idx_1")
    assert find_recordings(root) == [REC]
    assert seq.frame("sub_1", 0, undistort=False)[0, 0, 0] == 44  # frame 4's grey level
    assert seq.frame("master", 0).shape == (36, 64, 3)


def test_sub_views_use_the_inverse_of_their_transform_to_master(egobody):
    root, truth = egobody
    seq = load_egobody(root, REC)
    for cam in seq.cameras:
        np.testing.assert_allclose(cam.R, truth.cameras[cam.name]["R"], atol=1e-12)
        np.testing.assert_allclose(cam.t, truth.cameras[cam.name]["t"], atol=1e-12)
    assert seq.camera("master").model == "radial"
    np.testing.assert_allclose(seq.camera("master").centre, 0.0)


def test_ground_truth_projects_where_the_fixture_put_it_and_gaps_are_gaps(egobody, bodies):
    root, truth = egobody
    seq = load_egobody(root, REC, bodies=bodies)
    gt = seq.ground_truth()
    keep = slice(1, 5)  # fixture frames 4..7
    p0 = gt.names.index("body_idx_0")
    assert gt.valid[p0].tolist() == [True, True, False, True]  # no pickle at frame 6
    assert gt.valid[1].all() and gt.genders == ("male", "female")
    for p, name in enumerate(gt.names):
        ok = gt.valid[p]
        np.testing.assert_allclose(gt.joints[p][ok], truth.people[name]["joints"][keep][ok], atol=1e-5)
        for cam in seq.cameras:
            ref = truth.cameras[cam.name]
            joints = truth.people[name]["joints"][keep][ok].reshape(-1, 3)
            expected, _ = cv2.projectPoints(joints, cv2.Rodrigues(ref["R"])[0], ref["t"], ref["K"], ref["D"])
            np.testing.assert_allclose(cam.project(gt.joints[p][ok]).reshape(-1, 2), expected.reshape(-1, 2), atol=1e-4)
    assert np.all(gt.joints[p0, 2] == 0)


def test_missing_smpl_files_are_named(egobody, tmp_path, body):
    root, _ = egobody
    seq = load_egobody(root, REC)  # listing and frames need no body model
    with pytest.raises(InputError, match="gendered SMPL models.*--smpl-dir"):
        seq.ground_truth()
    smpl = tmp_path / "smpl"
    smpl.mkdir()
    shutil.copy(body.source if body.source != "procedural" else _procedural_path(), smpl / "SMPL_MALE.npz")
    seq = load_egobody(root, REC, bodies=gendered_bodies(smpl))
    with pytest.raises(InputError, match=r"SMPL_FEMALE.npz: missing SMPL model file for gender 'female'"):
        seq.ground_truth()
    male_only = seq.ground_truth(people=["body_idx_0"])
    assert male_only.valid.sum() == 3
    with pytest.raises(InputError, match="does not exist"):
        gendered_bodies(tmp_path / "nowhere")


def _procedural_path():
    from multithumbs.body.procedural import procedural_model_path

    return procedural_model_path()


def test_gated_data_not_present(tmp_path):
    with pytest.raises(InputError, match="data_info_release.csv: missing .*gated.*egobody.inf.ethz.ch"):
        load_egobody(tmp_path, REC)


def test_test_split_ground_truth_is_withheld(tmp_path, body, bodies):
    root = tmp_path / "egobody"
    make_egobody(root, body, split="test")
    seq = load_egobody(root, REC, bodies=bodies)
    assert any("withheld" in n for n in seq.notes)
    with pytest.raises(InputError, match="withholds the test split"):
        seq.ground_truth()


def test_layout_errors(egobody, tmp_path):
    root, _ = egobody
    copy = tmp_path / "root"
    shutil.copytree(root, copy)
    with pytest.raises(InputError, match="no recording 'recording_x'"):
        load_egobody(copy, "recording_x")
    with pytest.raises(InputError, match="unknown Kinect view 'sub_9'"):
        load_egobody(copy, REC, views=["master", "sub_9"])
    (copy / "calibrations" / REC / "cal_trans" / "kinect_11to12_color.json").unlink()
    with pytest.raises(InputError, match="kinect_11to12_color.json: missing"):
        load_egobody(copy, REC)
    assert load_egobody(copy, REC, views=["master"]).camera_names == ("master",)
    (copy / "kinect_cam_params" / "kinect_master" / "Color.json").write_text("{\"f\": [1, 1]}")
    with pytest.raises(InputError, match="Color.json: missing field 'camera_mtx'"):
        load_egobody(copy, REC, views=["master"])
    (copy / "data_splits.csv").unlink()
    with pytest.raises(InputError, match="data_splits.csv: missing"):
        load_egobody(copy, REC)
