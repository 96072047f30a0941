import importlib.util
import json

import numpy as np
import pytest
import torch
from scipy.spatial.transform import Rotation

from multithumbs.errors import InputError
from multithumbs.scene.learned import (
    LearnedSpaceConfig,
    confidence_to_unit,
    da3_outputs_to_shared_space,
    vggt_outputs_to_shared_space,
    vggt_pose_encoding_to_cameras,
    vggt_shared_space,
)

ALL = LearnedSpaceConfig(drop_percentile=0.0)
PROCESSED = (28, 42)   # (h, w) of the model's maps
ORIGINAL = (60, 90)


def _cameras(rng):
    R = Rotation.from_rotvec(rng.normal(size=(2, 3)) * 0.4).as_matrix()
    t = rng.normal(size=(2, 3))
    h, w = PROCESSED
    K = np.zeros((2, 3, 3))
    K[:, 0, 0], K[:, 1, 1] = [40.0, 35.0], [38.0, 30.0]
    K[:, 0, 2], K[:, 1, 2], K[:, 2, 2] = w / 2, h / 2, 1.0
    return R, t, K


def _check_space(space, R, t, depth):
    """Every point projects onto its original-resolution pixel with the space's own cameras, at its depth."""
    h, w = PROCESSED
    for k in range(2):
        sel = space.observed[k]
        cam = space.points[sel] @ space.R[k].T + space.t[k]
        uv = cam @ space.K[k].T
        uv = uv[:, :2] / uv[:, 2:]
        np.testing.assert_allclose(uv, space.pixels[k, sel], atol=1e-6)
        vs, us = np.mgrid[0:h, 0:w]
        np.testing.assert_allclose(cam[:, 2], depth[k][vs.ravel(), us.ravel()], rtol=1e-6)
        expected = np.c_[(us.ravel() + 0.5) * ORIGINAL[1] / w - 0.5, (vs.ravel() + 0.5) * ORIGINAL[0] / h - 0.5]
        np.testing.assert_allclose(space.pixels[k, sel], expected, atol=1e-9)
    np.testing.assert_allclose(space.R, R, atol=1e-6)
    np.testing.assert_allclose(space.t, t, atol=1e-6)


def test_vggt_pose_encoding_decodes_exactly():
    rng = np.random.default_rng(0)
    R, t, K = _cameras(rng)
    h, w = PROCESSED
    quat = Rotation.from_matrix(R).as_quat()                      # x, y, z, w (scalar last), VGGT's order
    fov_h, fov_w = 2 * np.arctan((h / 2) / K[:, 1, 1]), 2 * np.arctan((w / 2) / K[:, 0, 0])
    enc = np.concatenate([t, quat, fov_h[:, None], fov_w[:, None]], axis=1)
    extrinsics, intrinsics = vggt_pose_encoding_to_cameras(enc, PROCESSED)
    np.testing.assert_allclose(extrinsics[:, :, :3], R, atol=1e-12)
    np.testing.assert_allclose(extrinsics[:, :, 3], t, atol=1e-12)
    np.testing.assert_allclose(intrinsics, K, atol=1e-9)
    with pytest.raises(InputError, match="absT_quaR_FoV"):
        vggt_pose_encoding_to_cameras(np.zeros((2, 8)), PROCESSED)


def test_vggt_outputs_to_shared_space_exactly():
    rng = np.random.default_rng(1)
    R, t, K = _cameras(rng)
    h, w = PROCESSED
    quat = Rotation.from_matrix(R).as_quat()
    fov_h, fov_w = 2 * np.arctan((h / 2) / K[:, 1, 1]), 2 * np.arctan((w / 2) / K[:, 0, 0])
    pose_enc = torch.tensor(np.concatenate([t, quat, fov_h[:, None], fov_w[:, None]], 1)[None], dtype=torch.float64)
    depth = rng.uniform(1, 5, (2, h, w))
    conf = 1 + np.exp(rng.normal(size=(2, h, w)))
    predictions = {"pose_enc": pose_enc, "depth": torch.from_numpy(depth[None, ..., None]),
                   "depth_conf": torch.from_numpy(conf[None]),
                   "world_points": torch.zeros(1, 2, h, w, 3), "world_points_conf": torch.ones(1, 2, h, w)}
    space = vggt_outputs_to_shared_space(predictions, ORIGINAL, 17, ALL)
    assert space.source == "vggt" and space.cut_frame == 17 and space.image_size == ORIGINAL
    assert len(space.points) == 2 * h * w
    _check_space(space, R, t, depth)
    np.testing.assert_allclose(space.confidence, np.concatenate([1 - 1 / conf[0].ravel(), 1 - 1 / conf[1].ravel()]))
    # The point head, when chosen, supplies the points as they are.
    world = rng.normal(size=(2, h, w, 3))
    predictions["world_points"] = torch.from_numpy(world[None])
    head = vggt_outputs_to_shared_space(predictions, ORIGINAL, 17, LearnedSpaceConfig(drop_percentile=0.0,
                                                                                      points_from="point_head"))
    np.testing.assert_allclose(head.points, world.reshape(-1, 3))
    # Dropping the least confident fifth keeps the most confident points.
    dropped = vggt_outputs_to_shared_space(predictions, ORIGINAL, 17, LearnedSpaceConfig(drop_percentile=20))
    assert 0.75 * 2 * h * w < len(dropped.points) < 0.85 * 2 * h * w
    with pytest.raises(InputError, match="pose_enc"):
        vggt_outputs_to_shared_space({"depth": depth}, ORIGINAL, 17)


def test_da3_outputs_to_shared_space_exactly():
    rng = np.random.default_rng(2)
    R, t, K = _cameras(rng)
    h, w = PROCESSED
    depth = rng.uniform(1, 5, (2, h, w))
    conf = 1 + np.exp(rng.normal(size=(2, h, w)))
    extrinsics = np.concatenate([R, t[..., None]], axis=2)
    outputs = {"depth": torch.from_numpy(depth[None]), "depth_conf": torch.from_numpy(conf[None]),
               "extrinsics": torch.from_numpy(extrinsics[None]), "intrinsics": torch.from_numpy(K[None])}
    space = da3_outputs_to_shared_space(outputs, ORIGINAL, 9, ALL)
    assert space.source == "depth_anything_3"
    _check_space(space, R, t, depth)
    # The API's Prediction fields (no batch axis, 'conf', 4x4 extrinsics) convert the same way.
    homogeneous = np.tile(np.eye(4), (2, 1, 1))
    homogeneous[:, :3] = extrinsics
    same = da3_outputs_to_shared_space({"depth": depth, "conf": conf, "extrinsics": homogeneous, "intrinsics": K},
                                       ORIGINAL, 9, ALL)
    np.testing.assert_allclose(same.points, space.points)
    with pytest.raises(InputError, match="camera head"):
        da3_outputs_to_shared_space({"depth": depth, "conf": conf}, ORIGINAL, 9)


def test_confidence_to_unit():
    np.testing.assert_allclose(confidence_to_unit(np.array([1.0, 2.0, 4.0, 0.5])), [0.0, 0.5, 0.75, 0.0])


def test_vggt_run_path_feeds_the_documented_input():
    seen = {}

    def fake_vggt(images):  # VGGT's documented output format for the input it was given
        seen["shape"], seen["range"] = tuple(images.shape), (float(images.min()), float(images.max()))
        s, _, h, w = images.shape
        enc = torch.tensor([[0, 0, 0, 0, 0, 0, 1, 1.0, 1.4]] * s, dtype=torch.float32)[None]
        return {"pose_enc": enc, "depth": torch.ones(1, s, h, w, 1), "depth_conf": torch.full((1, s, h, w), 2.0)}

    frames = np.random.default_rng(3).integers(0, 256, (2, 90, 160, 3)).astype(np.uint8)
    space = vggt_shared_space(fake_vggt, frames[0], frames[1], 5, LearnedSpaceConfig(stride=4))
    assert seen["shape"] == (2, 3, 294, 518) and 0 <= seen["range"][0] and seen["range"][1] <= 1
    assert space.image_size == (90, 160) and space.source == "vggt"


@pytest.mark.skipif(importlib.util.find_spec("vggt") is not None, reason="vggt is installed")
def test_vggt_loader_names_the_missing_package(tmp_path):
    from multithumbs.scene.learned import load_vggt

    (tmp_path / "model.pt").write_bytes(b"")
    with pytest.raises(InputError, match="vggt"):
        load_vggt(tmp_path / "model.pt")
    with pytest.raises(InputError, match="no such"):
        load_vggt(tmp_path / "missing")


@pytest.mark.skipif(importlib.util.find_spec("depth_anything_3") is None, reason="depth-anything-3 not installed")
def test_da3_end_to_end_on_a_random_small_model(tmp_path, static_clip):
    from safetensors.torch import save_file

    from multithumbs.scene.learned import build_da3_network, da3_shared_space, load_da3

    torch.manual_seed(0)
    net = build_da3_network("da3-small")
    save_file({f"model.{k}": v.clone().contiguous() for k, v in net.state_dict().items()},
              str(tmp_path / "model.safetensors"))
    (tmp_path / "config.json").write_text(json.dumps({"model_name": "da3-small"}))
    model = load_da3(tmp_path)
    first = next(iter(net.state_dict().items()))
    torch.testing.assert_close(model.net.state_dict()[first[0]], first[1])
    cut = int(static_clip.world.cut_frames[0])
    frames = static_clip.video.frames
    space = da3_shared_space(model, frames[cut - 1], frames[cut], cut, LearnedSpaceConfig(process_res=112, stride=2))
    assert space.source == "depth_anything_3" and space.image_size == frames.shape[1:3]
    assert len(space.points) > 0 and np.isfinite(space.points).all()
    assert space.observed.sum(axis=1).min() > 0
    with pytest.raises(InputError, match="config.json"):
        (tmp_path / "config.json").unlink()
        load_da3(tmp_path)
