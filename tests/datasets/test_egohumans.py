import pickle
import shutil

import cv2
import numpy as np
import pytest

from multithumbs.datasets.egohumans import find_sequences, load_egohumans
from multithumbs.errors import InputError

SEQ = "01_tagging/001_tagging"
H4D_SEQ = "train/01_hugging/001_hugging"


def test_loads_cameras_people_and_frames(egohumans):
    root, seq_dir, truth = egohumans
    seq = load_egohumans(root, SEQ)
    assert seq.dataset == "egohumans" and seq.camera_names == ("cam01", "cam02")  # the 1408x1408 Aria camera is not exo
    assert seq.people == ("aria01", "aria02")
    np.testing.assert_array_equal(seq.frame_ids, truth.frame_ids)
    assert seq.alignment == "colmap+aria:aria01"
    assert find_sequences(root, "egohumans") == [SEQ]
    image = seq.frame("cam02", 0)
    assert image.shape == (48, 64, 3) and image.dtype == np.uint8


@pytest.mark.parametrize("fixture,sequence", [("egohumans", SEQ), ("harmony4d", H4D_SEQ)])
def test_scaled_alignment_yields_metric_cameras(request, fixture, sequence):
    """EgoHumans' aria01 transform scales by 2 (and aria02's differs: only the anchor may be used);
    Harmony4D's scale.npy halves COLMAP units. Both give the fixture's metric cameras."""
    root, _, truth = request.getfixturevalue(fixture)
    seq = load_egohumans(root, sequence, dataset=fixture)
    for cam in seq.cameras:
        np.testing.assert_allclose(cam.R, truth.cameras[cam.name]["R"], atol=1e-9)
        np.testing.assert_allclose(cam.t, truth.cameras[cam.name]["t"], atol=1e-9)
        np.testing.assert_allclose(cam.K, truth.cameras[cam.name]["K"])
    # Metric: the distance between the two camera centres is the fixture's, in metres.
    centres = [-c["R"].T @ c["t"] for c in truth.cameras.values()]
    assert np.linalg.norm(seq.cameras[0].centre - seq.cameras[1].centre) == pytest.approx(
        np.linalg.norm(centres[0] - centres[1]), abs=1e-9)
    assert seq.alignment == ("scale.npy" if fixture == "harmony4d" else "colmap+aria:aria01")


@pytest.mark.parametrize("fixture,sequence", [("egohumans", SEQ), ("harmony4d", H4D_SEQ)])
def test_ground_truth_joints_project_where_the_fixture_put_them(request, fixture, sequence):
    root, _, truth = request.getfixturevalue(fixture)
    seq = load_egohumans(root, sequence, dataset=fixture)
    gt = seq.ground_truth()
    for cam in seq.cameras:
        ref = truth.cameras[cam.name]
        rvec = cv2.Rodrigues(ref["R"])[0]
        for name in ("aria01", "aria02"):
            p = gt.names.index(name)
            joints = truth.people[name]["joints"]
            expected, _ = cv2.fisheye.projectPoints(joints.reshape(-1, 1, 3), rvec, ref["t"], ref["K"], ref["D"])
            got = cam.project(gt.joints[p])[gt.valid[p]]
            np.testing.assert_allclose(got, expected.reshape(joints.shape[:2] + (2,))[gt.valid[p]], atol=1e-6)


def test_undistorted_frames_put_the_blob_at_the_pinhole_projection(egohumans):
    """Each raw fisheye frame has a blob at the distorted projection of aria01's pelvis; after the loader's
    undistortion the blob sits at the pinhole projection with the same K."""
    root, _, truth = egohumans
    seq = load_egohumans(root, SEQ)
    gt = seq.ground_truth(people=["aria01"])
    for cam in seq.cameras:
        for i in range(seq.num_frames):
            image = seq.frame(cam.name, i).astype(float).sum(axis=-1)
            ys, xs = np.nonzero(image > 600)
            target = cam.project_undistorted(gt.joints[0, i, 0])
            raw = cam.project(gt.joints[0, i, 0])
            assert abs(xs.mean() - target[0]) < 1.0 and abs(ys.mean() - target[1]) < 1.0, (cam.name, i)
            raw_image = seq.frame(cam.name, i, undistort=False).astype(float).sum(axis=-1)
            ys, xs = np.nonzero(raw_image > 600)
            assert abs(xs.mean() - np.round(raw[0])) < 0.6 and abs(ys.mean() - np.round(raw[1])) < 0.6


def test_a_missing_person_is_a_gap(egohumans):
    root, _, truth = egohumans
    seq = load_egohumans(root, SEQ)
    gt = seq.ground_truth()
    p = gt.names.index("aria02")
    np.testing.assert_array_equal(gt.valid[p], truth.present["aria02"])
    assert not gt.valid[p, 3] and gt.valid[p].sum() == 5
    assert np.all(gt.joints[p, 3] == 0)
    np.testing.assert_allclose(gt.joints[p][gt.valid[p]], truth.people["aria02"]["joints"][gt.valid[p]])
    np.testing.assert_allclose(gt.transl[0], truth.people["aria01"]["transl"])
    sub = seq.ground_truth([3, 4], ["aria02"])
    assert sub.valid.tolist() == [[False, True]] and sub.frame_ids.tolist() == [4, 5]
    with_mesh = seq.ground_truth([0], with_vertices=True)
    assert with_mesh.vertices.shape[:2] == (2, 1) and with_mesh.vertices.dtype == np.float32


@pytest.mark.parametrize("remove,needle", [
    ("colmap/workplace/images.txt", "colmap/workplace/images.txt: missing"),
    ("colmap/workplace/cameras.txt", "colmap/workplace/cameras.txt: missing"),
    ("colmap/workplace/colmap_from_aria_transforms.pkl", "colmap_from_aria_transforms.pkl: missing"),
    ("processed_data/smpl", "processed_data/smpl: missing"),
])
def test_a_wrong_layout_names_the_first_missing_file(egohumans, tmp_path, remove, needle):
    root, seq_dir, _ = egohumans
    copy = tmp_path / "root"
    shutil.copytree(root, copy)
    target = copy / SEQ / remove
    shutil.rmtree(target) if target.is_dir() else target.unlink()
    with pytest.raises(InputError, match=needle) as info:
        load_egohumans(copy, SEQ)
    assert "\n" not in str(info.value)


def test_bad_files_are_named(egohumans, tmp_path):
    root, _, _ = egohumans
    copy = tmp_path / "root"
    shutil.copytree(root, copy)
    work = copy / SEQ / "colmap/workplace"
    with open(work / "colmap_from_aria_transforms.pkl", "wb") as f:
        pickle.dump({"aria02": np.eye(4)}, f)
    with pytest.raises(InputError, match="'aria01'"):
        load_egohumans(copy, SEQ)
    np.save(copy / SEQ / "processed_data/smpl/00002.npy", {"aria01": {"global_orient": np.zeros(3)}}, allow_pickle=True)
    (work / "colmap_from_aria_transforms.pkl").unlink()
    np.save(work / "scale.npy", np.eye(3))
    with pytest.raises(InputError, match="scale.npy: expected an invertible 4x4"):
        load_egohumans(copy, SEQ)
    np.save(work / "scale.npy", np.eye(4))
    seq = load_egohumans(copy, SEQ)
    with pytest.raises(InputError, match=r"00002.npy person aria01: missing field 'body_pose'"):
        seq.ground_truth([1])
    with pytest.raises(InputError, match="no camera 'cam09'"):
        seq.frame("cam09", 0)
    with pytest.raises(InputError, match="frame 6 is outside"):
        seq.frame("cam01", 6)
    with pytest.raises(InputError, match="no person 'aria07'"):
        seq.ground_truth(people=["aria07"])
    (copy / SEQ / "exo/cam01/images/00003.jpg").unlink()
    with pytest.raises(InputError, match="00003.jpg: frame image not found"):
        seq.frame("cam01", 2)


def test_excluded_cameras_and_people(egohumans):
    root, _, _ = egohumans
    seq = load_egohumans(root, SEQ, exclude_cameras=["cam02"], exclude_people=["aria02"], fps=30)
    assert seq.camera_names == ("cam01",) and seq.people == ("aria01",) and seq.fps == 30
    assert any("cam02: excluded" in n for n in seq.notes)
