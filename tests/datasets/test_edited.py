import numpy as np
import pytest

from multithumbs.datasets.edited import (
    BODY25_TO_SMPL, body25_to_smpl, describe_ava, describe_sitcoms, load_ava_boxes, load_ava_clip, load_sitcom_pairs,
)
from multithumbs.errors import InputError
from multithumbs.geometry import unproject
from multithumbs.metrics.gt_free import cross_shot_pck
from tests.datasets.fixtures import SITCOM, make_ava


def test_body25_maps_only_joints_with_the_same_meaning():
    kp = np.arange(25 * 3, dtype=float).reshape(25, 3)
    smpl = body25_to_smpl(kp[None])[0]
    assert smpl.shape == (24, 3)
    np.testing.assert_array_equal(smpl[16], kp[5])  # left shoulder <- LShoulder
    np.testing.assert_array_equal(smpl[0], kp[8])   # pelvis <- MidHip
    unmapped = sorted(set(range(24)) - set(BODY25_TO_SMPL))
    assert unmapped == [3, 6, 9, 10, 11, 13, 14, 15, 22, 23] and np.all(smpl[unmapped] == 0)
    with pytest.raises(InputError, match="BODY_25"):
        body25_to_smpl(np.zeros((18, 3)))


def test_ava_clip_has_the_shot_change_and_frames(ava):
    root, clip_path = ava
    clip = load_ava_clip(root, clip_path)
    assert clip.num_frames == 4 and clip.cut_frames.tolist() == [2] and clip.fps == 1.0
    assert clip.keypoints2d.shape == (1, 4, 24, 3) and clip.valid.all() and clip.linked.tolist() == [True]
    assert clip.shots().ranges == [(0, 2), (2, 4)]
    frames = list(clip.frames())
    assert len(frames) == 4 and frames[0].shape == (36, 64, 3)
    with np.load(clip_path) as data:
        np.testing.assert_array_equal(clip.keypoints_body25[0], data["body_keypoints"])
    boxes = load_ava_boxes(root / "ava_val_v2.2.csv")
    assert boxes.seconds.tolist() == [902, 902, 903] and boxes.person_ids.tolist() == [1, 0, 1]
    info = describe_ava(root)
    assert info["annotations"][0]["rows"] == 3 and info["clips"][0]["frames_present"] == 4
    assert info["frames"]["val/midframes"] == {"videos": 1, "images": 4}


def test_ava_frames_not_present_are_named(tmp_path):
    clip_path = make_ava(tmp_path, with_frames=False)
    clip = load_ava_clip(tmp_path, clip_path)
    with pytest.raises(InputError, match="0902.jpg: frame not present .*prepare_ava.py"):
        next(clip.frames())
    (tmp_path / "x.csv").write_text("a,1,2\n")
    with pytest.raises(InputError, match="x.csv line 1: expected 8 columns"):
        load_ava_boxes(tmp_path / "x.csv")
    np.savez(tmp_path / "bad.npz", imgname=np.array(["a.jpg"]))
    with pytest.raises(InputError, match="missing field 'shot'"):
        load_ava_clip(tmp_path, tmp_path / "bad.npz")


def test_sitcom_pair_links_one_identity_across_the_cut(sitcoms):
    root, data = sitcoms
    (clip,) = load_sitcom_pairs(root, SITCOM)
    assert clip.cut_frames.tolist() == [1] and clip.num_frames == 2
    # Two humans in each image, one linked: three people, the linked one seen on both sides.
    assert clip.valid.tolist() == [[True, False], [True, True], [False, True]]
    assert clip.linked.tolist() == [False, True, False]
    a, b = data["images"]
    np.testing.assert_allclose(clip.keypoints_body25[1, 0].reshape(-1), data["humans"][a][1]["openpose_keypoints"])
    np.testing.assert_allclose(clip.keypoints_body25[1, 1].reshape(-1), data["humans"][b][0]["openpose_keypoints"])
    np.testing.assert_allclose(clip.R[1], data["camtoworld"][1][:3, :3].T)
    with pytest.raises(InputError, match="not distributed.*ffmpeg"):
        next(clip.frames())
    info = describe_sitcoms(root)["locations"][0]
    assert info == {"location": SITCOM, "images": 2, "humans": 4, "pairs": 1, "clips": 1, "frames_present": 0,
                    "cameras": True}


def test_pck_star_scores_a_sitcom_clip(sitcoms):
    """Joints placed on the rays of the observed keypoints (through the clip's cameras) score 100 PCK*."""
    root, _ = sitcoms
    (clip,) = load_sitcom_pairs(root, SITCOM)
    kp = clip.keypoints2d
    p = kp.shape[0]
    joints = np.zeros((p, 2, 24, 3))
    for f in range(2):
        cam = unproject(kp[:, f, :, :2], np.full(kp.shape[:1] + (24,), 3.0), clip.K[f])
        joints[:, f] = (cam - clip.t[f]) @ clip.R[f]
    # The person keeps the same 3D joints across the cut: take them from the frame after it.
    joints[:, 0] = joints[:, 1]
    kp_scored = kp.copy()
    kp_scored[:, 0] = np.where(clip.valid[:, 0, None, None], kp[:, 0], 0.0)
    pck = cross_shot_pck(joints, clip.valid, kp_scored, clip.K, clip.R, clip.t, clip.cut_frames)
    assert pck.forward.mask[0, 1].sum() > 0 and pck.forward.mean() == pytest.approx(100.0)
    assert pck.forward.mask[0, [0, 2]].sum() == 0  # unlinked people are not scored


def test_sitcom_bad_pairs(sitcoms, tmp_path):
    root, data = sitcoms
    (tmp_path / "human_data").mkdir()
    (tmp_path / "human_pairs").mkdir()
    (tmp_path / "human_data" / "X.json").write_text((root / "human_data" / f"{SITCOM}.json").read_text())
    (tmp_path / "human_pairs" / "X.json").write_text(f'[["{data["images"][0]}", 5, "{data["images"][1]}", 0]]')
    with pytest.raises(InputError, match="has no human 5"):
        load_sitcom_pairs(tmp_path, "X")
    with pytest.raises(InputError, match="Y.json: missing"):
        load_sitcom_pairs(tmp_path, "Y")
