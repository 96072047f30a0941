import hashlib
import json
import shutil
import time

import cv2
import numpy as np
import pytest

from multithumbs.datasets.benchmark import build_clip, iter_benchmark, level_transform
from multithumbs.datasets.catalog import open_sequence
from multithumbs.datasets.clip_specs import ClipSpec
from multithumbs.errors import InputError
from multithumbs.io import load_ground_truth
from multithumbs.video import probe_video, read_frames
from tests.datasets.fixtures import REC, G

SEQ = "01_tagging/001_tagging"
SPEC = dict(name="eh_cut3", dataset="egohumans", sequence=SEQ, cameras=["cam01", "cam02"], cuts=[3], num_frames=6)


def sha(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.fixture(scope="module")
def built(egohumans, tmp_path_factory):
    root, _, truth = egohumans
    seq = open_sequence(root, "egohumans", SEQ)
    clip = build_clip(ClipSpec(**SPEC), seq, tmp_path_factory.mktemp("clips"))
    gt, extras = load_ground_truth(clip / "ground_truth.npz")
    return clip, gt, extras, truth, seq


def test_clip_folder_has_the_synthetic_scene_files(built):
    clip, gt, extras, _, _ = built
    assert sorted(p.name for p in clip.iterdir()) == ["ground_truth.npz", "spec.json", "video.mp4"]
    assert json.loads((clip / "spec.json").read_text()) == ClipSpec(**SPEC).to_json()
    info = probe_video(clip / "video.mp4")
    assert info.num_frames == 6 and info.image_size == (48, 64) and gt.world.fps == 20.0
    assert gt.world.cut_frames.tolist() == [3] and gt.camera_ids.tolist() == [0, 0, 0, 1, 1, 1]
    assert gt.metadata["people"] == ["aria01", "aria02"] and gt.metadata["cameras"] == ["cam01", "cam02"]
    assert extras["frame_ids"].tolist() == [1, 2, 3, 4, 5, 6]
    assert gt.world.id_map.tolist() == [[0, 0, 0], [0, 1, 1], [1, 0, 0], [1, 1, 1]]


def test_cut_switches_cameras_while_world_ground_truth_stays_continuous(built):
    clip, gt, extras, truth, seq = built
    w = gt.world
    np.testing.assert_array_equal(w.R[:3], np.broadcast_to(w.R[0], (3, 3, 3)))
    np.testing.assert_array_equal(w.R[3:], np.broadcast_to(w.R[3], (3, 3, 3)))
    assert not np.allclose(w.R[2], w.R[3]) and not np.allclose(w.K[2], w.K[3])
    # World joints are the fixture's, moved by one rigid transform for all frames (no jump at the cut).
    Q = np.array(gt.metadata["level_transform"]["Q"])
    u = np.array(gt.metadata["level_transform"]["u"])
    for p, name in enumerate(gt.metadata["people"]):
        ok = w.valid[p]
        np.testing.assert_allclose(extras["joints"][p][ok], (truth.people[name]["joints"] @ Q.T + u)[ok], atol=1e-9)
    # Camera-frame ground truth switches: keypoints are each frame's camera's pinhole projection,
    # i.e. where OpenCV undistorts the fixture's fisheye projection to.
    for f in range(6):
        name = ("cam01", "cam02")[gt.camera_ids[f]]
        ref = truth.cameras[name]
        joints = truth.people["aria01"]["joints"][f]
        raw, _ = cv2.fisheye.projectPoints(joints[:, None], cv2.Rodrigues(ref["R"])[0], ref["t"], ref["K"], ref["D"])
        pinhole = cv2.fisheye.undistortPoints(raw, ref["K"], ref["D"], P=ref["K"]).reshape(-1, 2)
        inside = w.keypoints2d[0, f, :, 2] > 0
        np.testing.assert_allclose(w.keypoints2d[0, f, inside, :2], pinhole[inside], atol=1e-3)
    assert gt.visible[1].tolist() == [True, True, True, False, True, True]  # aria02's gap stays a gap


def test_video_frames_show_the_blob_at_the_ground_truth_keypoint(built):
    clip, gt, _, _, _ = built
    frames = read_frames(clip / "video.mp4", range(6))
    for f, frame in enumerate(frames):
        bright = frame.astype(float).sum(axis=-1)
        ys, xs = np.nonzero(bright > bright.max() * 0.6)
        pelvis = gt.world.keypoints2d[0, f, 0, :2]
        assert abs(xs.mean() - pelvis[0]) < 1.5 and abs(ys.mean() - pelvis[1]) < 1.5, f


def test_levelled_world_is_z_up_with_the_floor_at_zero(built, body):
    _, gt, extras, _, _ = built
    w = gt.world
    out = body.forward(w.global_orient, w.body_pose, w.betas, w.transl)
    np.testing.assert_allclose(out.joints.numpy()[w.valid], extras["joints"][w.valid], atol=1e-5)
    lowest = out.vertices.numpy()[w.valid][..., 2].min(axis=-1)
    np.testing.assert_allclose(lowest, 0.0, atol=1e-4)  # every body stands on z = 0
    Q = np.array(gt.metadata["level_transform"]["Q"])
    np.testing.assert_allclose((Q @ G)[2], [0, 0, 1], atol=1e-5)  # the fixture's level world's up is +z


def test_level_transform_falls_back_to_the_bodies_up_and_needs_people():
    joints = np.zeros((1, 2, 24, 3))
    joints[..., 12, :] = [0.0, 0.0, 0.5]
    joints[..., (7, 8, 10, 11), :] = [0.0, 0.0, -0.9]
    Q, u = level_transform(joints, np.ones((1, 2), bool))  # one still person: no floor plane
    np.testing.assert_allclose(Q, np.eye(3), atol=1e-12)
    np.testing.assert_allclose(u, [0, 0, 0.9])
    with pytest.raises(InputError, match="level = false"):
        level_transform(joints, np.zeros((1, 2), bool))


def test_same_spec_gives_byte_identical_ground_truth(egohumans, built, tmp_path, monkeypatch):
    clip, *_ = built
    root, _, _ = egohumans
    real_time = time.time
    monkeypatch.setattr(time, "time", lambda: real_time() + 3 * 86400)  # zip entries would carry another date
    again = build_clip(ClipSpec(**SPEC), open_sequence(root, "egohumans", SEQ), tmp_path)
    assert sha(again / "ground_truth.npz") == sha(clip / "ground_truth.npz")
    assert (again / "spec.json").read_bytes() == (clip / "spec.json").read_bytes()


def test_unlevelled_resized_strided_clip(egohumans, tmp_path):
    root, _, truth = egohumans
    spec = ClipSpec(name="small", dataset="egohumans", sequence=SEQ, cameras=("cam02", "cam01"), cuts=(2,),
                    num_frames=3, start=1, stride=2, people=("aria02",), image_size=(24, 32), level=False, fps=5)
    clip = build_clip(spec, open_sequence(root, "egohumans", SEQ), tmp_path)
    gt, extras = load_ground_truth(clip / "ground_truth.npz")
    assert extras["frame_ids"].tolist() == [2, 4, 6] and gt.world.valid.tolist() == [[True, False, True]]
    assert gt.world.image_size == (24, 32) and probe_video(clip / "video.mp4").image_size == (24, 32)
    assert gt.world.fps == 5 and gt.metadata["people"] == ["aria02"]
    np.testing.assert_allclose(extras["joints"][0, [0, 2]], truth.people["aria02"]["joints"][[1, 5]])
    ref = truth.cameras["cam02"]
    K_half = ref["K"].copy()
    K_half[:2] *= 0.5
    K_half[:2, 2] -= 0.25  # pixel centres at integers: u' = (u + 0.5) / 2 - 0.5
    np.testing.assert_allclose(gt.world.K[0], K_half)
    np.testing.assert_allclose(gt.world.R[0], ref["R"])


def test_egobody_and_harmony4d_clips(egobody, harmony4d, bodies, tmp_path):
    root, truth = egobody
    spec = ClipSpec(name="eb", dataset="egobody", sequence=REC, cameras=("master", "sub_1"), cuts=(2,), num_frames=4)
    (name, clip), = iter_benchmark([spec], root, tmp_path, bodies=bodies)
    gt, extras = load_ground_truth(clip / "ground_truth.npz")
    assert name == "eb" and extras["frame_ids"].tolist() == [4, 5, 6, 7]
    assert gt.world.valid.tolist() == [[True, True, False, True], [True, True, True, True]]
    assert gt.metadata["genders"] == ["male", "female"] and gt.world.image_size == (36, 64)
    root, _, _ = harmony4d
    spec = ClipSpec(name="h4d", dataset="harmony4d", sequence="train/01_hugging/001_hugging",
                    cameras=("cam02", "cam01"), cuts=(4,), num_frames=6)
    (_, clip), = iter_benchmark([spec], root, tmp_path)
    gt, _ = load_ground_truth(clip / "ground_truth.npz")
    assert gt.metadata["alignment"] == "scale.npy" and gt.camera_ids.tolist() == [0, 0, 0, 0, 1, 1]


def test_iter_benchmark_reuses_finished_clips_and_refuses_to_overwrite(egohumans, tmp_path):
    root, _, _ = egohumans
    spec_file = tmp_path / "bench.json"
    spec_file.write_text(json.dumps([SPEC, dict(SPEC, name="eh_cut2", cuts=[2])]))
    out = tmp_path / "out"
    first = dict(iter_benchmark([spec_file], root, out))
    assert list(first) == ["eh_cut3", "eh_cut2"]
    stamp = (out / "eh_cut3" / "ground_truth.npz").stat().st_mtime_ns
    assert dict(iter_benchmark([spec_file], root, out)) == first  # reused, not rebuilt
    assert (out / "eh_cut3" / "ground_truth.npz").stat().st_mtime_ns == stamp
    spec_file.write_text(json.dumps([dict(SPEC, cuts=[4])]))
    with pytest.raises(InputError, match="eh_cut3/video.mp4: already exists .*--overwrite"):
        list(iter_benchmark([spec_file], root, out))
    (name, clip), = iter_benchmark([spec_file], root, out, overwrite=True)
    gt, _ = load_ground_truth(clip / "ground_truth.npz")
    assert gt.world.cut_frames.tolist() == [4]


def test_bad_specs_against_the_data_and_no_half_written_clip(egohumans, tmp_path):
    root, _, _ = egohumans
    seq = open_sequence(root, "egohumans", SEQ)
    with pytest.raises(InputError, match="no camera 'cam07'"):
        build_clip(ClipSpec(**dict(SPEC, cameras=["cam01", "cam07"])), seq, tmp_path)
    with pytest.raises(InputError, match="frame 6 is outside"):
        build_clip(ClipSpec(**dict(SPEC, start=1)), seq, tmp_path)
    with pytest.raises(InputError, match="no person 'aria09'"):
        build_clip(ClipSpec(**dict(SPEC, people=["aria09"])), seq, tmp_path)
    copy = tmp_path / "root"
    shutil.copytree(root, copy)
    (copy / SEQ / "exo/cam02/images/00005.jpg").unlink()
    with pytest.raises(InputError, match="00005.jpg: frame image not found"):
        build_clip(ClipSpec(**SPEC), open_sequence(copy, "egohumans", SEQ), tmp_path / "out")
    assert [p.name for p in (tmp_path / "out" / "eh_cut3").iterdir()] == []
