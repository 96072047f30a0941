import importlib.util

import numpy as np
import pytest
import torch
from scipy.spatial.transform import Rotation

from multithumbs.errors import InputError
from multithumbs.perception.camera import hmr2_intrinsics
from multithumbs.perception.hmr2 import assemble_tracks, box_iou, hmr2_outputs_to_people, link_boxes, require_hmr2
from multithumbs.types import Shots

HAS_HMR2 = importlib.util.find_spec("hmr2") is not None


@pytest.mark.skipif(HAS_HMR2, reason="hmr2 is installed here")
def test_missing_hmr2_is_a_clear_error():
    with pytest.raises(InputError, match="the hmr2 package is not installed") as e:
        require_hmr2()
    assert "\n" not in str(e.value) and "phalp:" in str(e.value)


def _synthetic_outputs(rng, b, image_size, box_center, box_size, transl_full):
    """HMR2's documented outputs for bodies at known full-image translations."""
    h, w = image_size
    f = 5000 / 256 * max(h, w)
    # Invert cam_crop_to_full: s from tz, then tx, ty.
    s = 2 * f / (box_size * transl_full[:, 2])
    bs = box_size * s
    tx = transl_full[:, 0] - 2 * (box_center[:, 0] - w / 2) / bs
    ty = transl_full[:, 1] - 2 * (box_center[:, 1] - h / 2) / bs
    orient = Rotation.random(b, random_state=1).as_matrix()[:, None]
    pose = Rotation.random(b * 23, random_state=2).as_matrix().reshape(b, 23, 3, 3)
    joints = rng.normal(0, 0.3, (b, 44, 3))
    return {
        "pred_smpl_params": {"global_orient": torch.tensor(orient), "body_pose": torch.tensor(pose),
                             "betas": torch.tensor(rng.normal(size=(b, 10)))},
        "pred_cam": torch.tensor(np.stack([s, tx, ty], 1)),
        "pred_keypoints_3d": torch.tensor(joints),
        "pred_keypoints_2d": torch.zeros(b, 44, 2),
        "focal_length": torch.full((b, 2), 5000.0),
    }, orient, pose, joints


def test_output_conversion_on_synthetic_tensors():
    rng = np.random.default_rng(0)
    image_size = (360, 640)
    centre, size = np.array([[300.0, 200.0], [500.0, 150.0]]), np.array([220.0, 180.0])
    transl = np.array([[0.3, 0.2, 12.0], [-1.0, 0.5, 20.0]])
    outputs, orient, pose, joints = _synthetic_outputs(rng, 2, image_size, centre, size, transl)
    people = hmr2_outputs_to_people(outputs, torch.tensor(centre), torch.tensor(size), image_size)
    np.testing.assert_allclose(people["transl"], transl, rtol=1e-9)
    np.testing.assert_allclose(Rotation.from_rotvec(people["global_orient"]).as_matrix(), orient[:, 0], atol=1e-9)
    np.testing.assert_allclose(Rotation.from_rotvec(people["body_pose"].reshape(-1, 3)).as_matrix(),
                               pose.reshape(-1, 3, 3), atol=1e-9)
    assert people["betas"].shape == (2, 10) and people["keypoints2d"].shape == (2, 24, 3)
    K = hmr2_intrinsics(image_size, padded_square=False)
    np.testing.assert_allclose(people["K"], K)
    # The pelvis keypoint is OpenPose's mid-hip (index 8) projected with K.
    uvw = K @ (joints[0, 8] + transl[0])
    np.testing.assert_allclose(people["keypoints2d"][0, 0, :2], uvw[:2] / uvw[2], atol=1e-9)
    assert np.all(people["keypoints2d"][:, [3, 6, 9, 15, 22, 23], 2] == 0)


def test_output_conversion_without_3d_joints_uses_the_crop():
    rng = np.random.default_rng(1)
    centre, size = np.array([[300.0, 200.0]]), np.array([200.0])
    outputs, *_ = _synthetic_outputs(rng, 1, (360, 640), centre, size, np.array([[0.0, 0.0, 10.0]]))
    del outputs["pred_keypoints_3d"]
    outputs["pred_keypoints_2d"][0, 8] = torch.tensor([0.25, -0.5])  # crop units
    people = hmr2_outputs_to_people(outputs, centre, size, (360, 640))
    np.testing.assert_allclose(people["keypoints2d"][0, 0], [300 + 50 - 0.5, 200 - 100 - 0.5, 1.0])


def test_box_iou():
    a = np.array([[0, 0, 10, 10]])
    b = np.array([[5, 0, 15, 10], [20, 20, 30, 30]])
    np.testing.assert_allclose(box_iou(a, b), [[50 / 150, 0.0]])


def test_link_boxes_keeps_ids_through_a_missed_frame():
    frames = [np.array([[0, 0, 10, 20], [50, 0, 60, 20]]),
              np.array([[52, 0, 62, 20], [2, 0, 12, 20]]),
              np.array([[4, 0, 14, 20]]),                        # the second person is missed
              np.array([[56, 0, 66, 20], [6, 0, 16, 20], [100, 0, 110, 20]])]
    ids = link_boxes(frames)
    assert ids[0].tolist() == [0, 1]
    assert ids[1].tolist() == [1, 0]
    assert ids[2].tolist() == [0]
    assert ids[3].tolist() == [1, 0, 2]


def test_assemble_tracks_splits_at_cuts():
    shots = Shots(np.array([2]), 30.0, 4, np.zeros(4))
    det = lambda boxes: {"boxes": np.array(boxes, float), "masks": None, "global_orient": np.zeros((len(boxes), 3)),
                         "body_pose": np.zeros((len(boxes), 23, 3)), "betas": np.ones((len(boxes), 10)),
                         "transl": np.tile([0, 0, 5.0], (len(boxes), 1)), "keypoints2d": np.zeros((len(boxes), 24, 3))}
    detections = [det([[0, 0, 10, 20]]), det([[1, 0, 11, 20]]), det([[1, 0, 11, 20], [40, 0, 50, 20]]), det([])]
    tracks, boxes = assemble_tracks(shots, (32, 64), np.eye(3), detections)
    assert [tr.num_people for tr in tracks] == [1, 2]
    assert tracks[0].valid.tolist() == [[True, True]]
    assert tracks[1].valid.tolist() == [[True, False], [True, False]]
    np.testing.assert_allclose(tracks[1].betas, 1.0)
    assert boxes[1].shape == (2, 2, 4)


# --- device selection and model loading (hmr2 cannot be installed here: fakes stand in for it) ---

def test_device_is_cuda_when_present():
    from multithumbs.perception.hmr2 import select_device

    assert select_device("auto", cuda_available=True) == "cuda"
    assert select_device(None, cuda_available=False) == "cpu"
    assert select_device("cpu", cuda_available=True) == "cpu"
    assert select_device("cuda:1", cuda_available=True) == "cuda:1"


@pytest.mark.parametrize("device, match", [("cuda", "CUDA is not available on this machine"),
                                           ("gpu0", "not a torch device")])
def test_device_errors_are_one_line(device, match):
    from multithumbs.perception.hmr2 import select_device

    with pytest.raises(InputError, match=match) as e:
        select_device(device, cuda_available=False)
    assert "\n" not in str(e.value) and device in str(e.value)


def _fake_hmr2(monkeypatch, init_renderer_ok: bool, load_error: Exception | None = None):
    import sys
    import types

    calls = {}

    class Cfg(dict):
        def __init__(self):
            super().__init__()
            self.MODEL = types.SimpleNamespace(BACKBONE=types.SimpleNamespace(TYPE="resnet"))

    class HMR2:
        @staticmethod
        def load_from_checkpoint(path, strict, cfg, **kwargs):
            if not init_renderer_ok:
                raise TypeError("unexpected keyword argument 'init_renderer'")
            calls["kwargs"] = kwargs
            return "model"

    def load_hmr2(path):
        raise load_error

    models = types.ModuleType("hmr2.models")
    models.HMR2, models.load_hmr2 = HMR2, load_hmr2
    configs = types.ModuleType("hmr2.configs")
    configs.get_config = lambda path, update_cachedir: Cfg()
    monkeypatch.setitem(sys.modules, "hmr2", types.ModuleType("hmr2"))
    monkeypatch.setitem(sys.modules, "hmr2.models", models)
    monkeypatch.setitem(sys.modules, "hmr2.configs", configs)
    return calls


def _checkpoint(tmp_path):
    ckpt = tmp_path / "logs" / "train" / "checkpoints" / "epoch=35.ckpt"
    ckpt.parent.mkdir(parents=True)
    ckpt.write_bytes(b"")
    (tmp_path / "logs" / "train" / "model_config.yaml").write_text("")
    return ckpt


def test_model_loads_without_the_renderer(monkeypatch, tmp_path):
    from multithumbs.perception.hmr2 import load_hmr2_model

    calls = _fake_hmr2(monkeypatch, init_renderer_ok=True)
    model, _ = load_hmr2_model(_checkpoint(tmp_path))
    assert model == "model" and calls["kwargs"] == {"init_renderer": False}


def test_renderer_that_needs_egl_is_named(monkeypatch, tmp_path):
    from multithumbs.perception.hmr2 import load_hmr2_model

    _fake_hmr2(monkeypatch, init_renderer_ok=False, load_error=ImportError("Unable to load EGL library"))
    with pytest.raises(InputError, match="mesh renderer that needs EGL.*PYOPENGL_PLATFORM=egl") as e:
        load_hmr2_model(_checkpoint(tmp_path))
    assert "\n" not in str(e.value)


def test_missing_checkpoint_and_config_are_named(monkeypatch, tmp_path):
    from multithumbs.perception.hmr2 import load_hmr2_model

    _fake_hmr2(monkeypatch, init_renderer_ok=True)
    with pytest.raises(InputError, match="checkpoint .*none.ckpt not found"):
        load_hmr2_model(tmp_path / "none.ckpt")
    ckpt = _checkpoint(tmp_path)
    (ckpt.parent.parent / "model_config.yaml").unlink()
    with pytest.raises(InputError, match="model_config.yaml not found"):
        load_hmr2_model(ckpt)
