"""Learned scene priors at a cut: VGGT and Depth-Anything-3 adapters (DESIGN §1 stage 4, GPU path).

Both models take the two boundary frames and return, per frame, a camera and a dense depth map with
confidences; :func:`depth_maps_to_shared_space` turns that into a :class:`~multithumbs.types.SharedSpace`
(points of frame ``k`` observed in frame ``k`` only, as a point map is; the world is the model's, scale
arbitrary). Weights come from a local path only and are never downloaded at run time.

VGGT (``vggt`` package, from its GitHub repository; not on PyPI; imported only when chosen):
    images resized to width 518 and a height that is a multiple of 14, values in [0, 1], ``(S, 3, H, W)``.
    Outputs: ``pose_enc (B, S, 9)`` in the ``absT_quaR_FoV`` encoding — translation ``T (3)``, quaternion
    ``(x, y, z, w)`` scalar last, vertical and horizontal field of view ``fov_h, fov_w`` (radians) — whose
    decoding (VGGT's ``pose_encoding_to_extri_intri``) is the OpenCV camera-from-world ``[R | T]`` and
    ``fy = (H/2) / tan(fov_h/2)``, ``fx = (W/2) / tan(fov_w/2)``, principal point ``(W/2, H/2)``;
    ``depth (B, S, H, W, 1)`` with ``depth_conf (B, S, H, W)``; ``world_points (B, S, H, W, 3)`` with
    ``world_points_conf``. The world is the first camera's. Confidences are ``1 + exp(x) >= 1``.
Depth-Anything-3 (``depth-anything-3`` on PyPI, Apache-2.0 code; Base/Small/Metric weights Apache-2.0):
    ImageNet-normalised images whose longer side is at most ``process_res`` (multiples of 14),
    ``(B, N, 3, H, W)``. Outputs: ``depth (B, N, H, W)``, ``depth_conf (B, N, H, W)`` (``>= 1``),
    ``extrinsics (B, N, 3, 4)`` OpenCV world-to-camera, ``intrinsics (B, N, 3, 3)`` at the processed size.
    The network is built from the package's own config registry and its ``model.safetensors`` loaded from
    the user's folder (what ``DepthAnything3.from_pretrained`` reads); ``depth_anything_3.api`` is not
    imported because it needs torchvision, whose PyPI build does not load beside this CPU torch.

Confidence in [0, 1] is ``1 - 1 / conf`` for both. Depth, not VGGT's point head, makes the points by
default (unprojecting depth with the predicted camera is the more accurate of the two, per VGGT's authors).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from scipy.spatial.transform import Rotation

from multithumbs.errors import InputError
from multithumbs.types import SharedSpace

VGGT_WIDTH = 518
PATCH = 14
IMAGENET_MEAN = np.array([0.485, 0.456, 0.406], np.float32)
IMAGENET_STD = np.array([0.229, 0.224, 0.225], np.float32)


@dataclass(frozen=True)
class LearnedSpaceConfig:
    """Turning a learned model's depth maps into a shared space.

    Attributes:
        stride: keep every ``stride``-th pixel of the model's maps in each direction.
        drop_percentile: the least confident points, this percentage of each frame, are dropped.
        points_from: ``"depth"`` (unproject depth with the predicted camera, default) or ``"point_head"``
            (VGGT's world points).
        device: torch device of the model.
        process_res: Depth-Anything-3 processing resolution (longer side, pixels).
    """

    stride: int = 1
    drop_percentile: float = 20.0
    points_from: str = "depth"
    device: str = "cpu"
    process_res: int = 504


# ----------------------------------------------------------------------------------------------------
# Conversions (pure numpy; tested exactly)


def vggt_pose_encoding_to_cameras(pose_enc: np.ndarray, image_hw: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Decode VGGT's ``absT_quaR_FoV`` encoding ``(..., 9)`` to extrinsics ``(..., 3, 4)`` and intrinsics ``(..., 3, 3)``.

    Extrinsics are OpenCV camera-from-world ``[R | T]``; intrinsics are at the processed size ``image_hw``
    with the principal point at ``(W/2, H/2)``, as VGGT's ``pose_encoding_to_extri_intri``.
    """
    enc = np.asarray(pose_enc, np.float64)
    if enc.shape[-1] != 9:
        raise InputError(f"pose_enc: expected (..., 9) absT_quaR_FoV encodings, got {enc.shape}")
    T, quat, fov_h, fov_w = enc[..., :3], enc[..., 3:7], enc[..., 7], enc[..., 8]
    R = Rotation.from_quat(quat.reshape(-1, 4)).as_matrix().reshape(*enc.shape[:-1], 3, 3)  # scalar last
    extrinsics = np.concatenate([R, T[..., None]], axis=-1)
    h, w = image_hw
    K = np.zeros((*enc.shape[:-1], 3, 3))
    K[..., 0, 0] = (w / 2.0) / np.tan(fov_w / 2.0)
    K[..., 1, 1] = (h / 2.0) / np.tan(fov_h / 2.0)
    K[..., 0, 2] = w / 2.0
    K[..., 1, 2] = h / 2.0
    K[..., 2, 2] = 1.0
    return extrinsics, K


def confidence_to_unit(conf: np.ndarray) -> np.ndarray:
    """Map the models' ``1 + exp(x)`` confidences (``>= 1``) to [0, 1]: ``1 - 1/conf``."""
    conf = np.asarray(conf, np.float64)
    return np.clip(1.0 - 1.0 / np.maximum(conf, 1.0), 0.0, 1.0)


def _resize_intrinsics(K: np.ndarray, processed_hw: tuple[int, int], image_hw: tuple[int, int]) -> np.ndarray:
    """Intrinsics at the processed size to the original size (a plain resize; pixel centres at integers)."""
    sy, sx = image_hw[0] / processed_hw[0], image_hw[1] / processed_hw[1]
    out = np.array(K, np.float64, copy=True)
    out[..., 0, 0] *= sx
    out[..., 1, 1] *= sy
    out[..., 0, 2] = (out[..., 0, 2] + 0.5) * sx - 0.5
    out[..., 1, 2] = (out[..., 1, 2] + 0.5) * sy - 0.5
    return out


def depth_maps_to_shared_space(depth: np.ndarray, conf: np.ndarray, extrinsics: np.ndarray, intrinsics: np.ndarray,
                               image_size: tuple[int, int], cut_frame: int, source: str,
                               config: LearnedSpaceConfig = LearnedSpaceConfig(),
                               world_points: np.ndarray | None = None) -> SharedSpace:
    """A shared space from two frames' depth maps and cameras at the model's processed size.

    Args:
        depth: ``(2, h, w)`` z-depth (a trailing size-1 axis is accepted).
        conf: ``(2, h, w)`` confidences (``>= 1``, mapped by :func:`confidence_to_unit`).
        extrinsics: ``(2, 3, 4)`` or ``(2, 4, 4)`` OpenCV world-to-camera.
        intrinsics: ``(2, 3, 3)`` at the processed size ``(h, w)``.
        image_size: ``(H, W)`` of the original frames (pixels are mapped back to it).
        world_points: ``(2, h, w, 3)`` used instead of unprojected depth when ``config.points_from`` is
            ``"point_head"``.
    """
    depth = np.asarray(depth, np.float64)
    if depth.ndim == 4 and depth.shape[-1] == 1:
        depth = depth[..., 0]
    if depth.ndim != 3 or depth.shape[0] != 2:
        raise InputError(f"depth: expected (2, h, w) depth maps of the two boundary frames, got {depth.shape}")
    conf = np.asarray(conf, np.float64)
    if conf.shape != depth.shape:
        raise InputError(f"conf: expected {depth.shape} like depth, got {conf.shape}")
    extrinsics = np.asarray(extrinsics, np.float64)[:, :3, :4]
    if extrinsics.shape != (2, 3, 4):
        raise InputError(f"extrinsics: expected (2, 3, 4) or (2, 4, 4), got {np.shape(extrinsics)}")
    intrinsics = np.asarray(intrinsics, np.float64)
    if intrinsics.shape != (2, 3, 3):
        raise InputError(f"intrinsics: expected (2, 3, 3), got {intrinsics.shape}")
    if config.points_from not in ("depth", "point_head"):
        raise InputError(f"points_from {config.points_from!r}: use 'depth' or 'point_head'")
    if config.points_from == "point_head" and world_points is None:
        raise InputError("world_points: the point head was chosen but no world points were given")
    h, w = depth.shape[1:]
    H, W = (int(s) for s in image_size)
    R, t = extrinsics[:, :, :3], extrinsics[:, :, 3]
    vs, us = np.mgrid[0:h:config.stride, 0:w:config.stride]
    us, vs = us.ravel(), vs.ravel()
    unit = confidence_to_unit(conf)
    points, pixels, observed, confidence = [], [], [], []
    for k in range(2):
        d, c = depth[k, vs, us], unit[k, vs, us]
        keep = np.isfinite(d) & (d > 0)
        if keep.any() and config.drop_percentile > 0:
            keep &= c >= np.percentile(c[keep], config.drop_percentile)
        u, v = us[keep].astype(np.float64), vs[keep].astype(np.float64)
        if config.points_from == "point_head":
            world = np.asarray(world_points, np.float64)[k, vs[keep], us[keep]]
        else:
            cam = np.c_[u, v, np.ones(len(u))] @ np.linalg.inv(intrinsics[k]).T * d[keep, None]
            world = (cam - t[k]) @ R[k]                                   # R^T (x - t)
        pix = np.zeros((2, len(u), 2))
        pix[k] = np.c_[(u + 0.5) * W / w - 0.5, (v + 0.5) * H / h - 0.5]
        obs = np.zeros((2, len(u)), bool)
        obs[k] = True
        points.append(world)
        pixels.append(pix)
        observed.append(obs)
        confidence.append(c[keep])
    return SharedSpace(cut_frame=cut_frame, K=_resize_intrinsics(intrinsics, (h, w), (H, W)), R=R, t=t,
                       points=np.concatenate(points), pixels=np.concatenate(pixels, axis=1),
                       observed=np.concatenate(observed, axis=1), confidence=np.concatenate(confidence),
                       image_size=(H, W), source=source)


def vggt_outputs_to_shared_space(predictions: dict, image_size: tuple[int, int], cut_frame: int,
                                 config: LearnedSpaceConfig = LearnedSpaceConfig()) -> SharedSpace:
    """VGGT's prediction dict (batch of one, two frames; tensors or arrays) to a :class:`SharedSpace`."""
    get = lambda key: None if predictions.get(key) is None else _numpy(predictions[key])
    pose_enc, depth, depth_conf = get("pose_enc"), get("depth"), get("depth_conf")
    if pose_enc is None or depth is None or depth_conf is None:
        raise InputError("VGGT predictions: need pose_enc, depth and depth_conf")
    pose_enc, depth, depth_conf = _unbatch(pose_enc, 2), _unbatch(depth, 3), _unbatch(depth_conf, 3)
    if depth.ndim == 4:
        depth = depth[..., 0]
    processed = depth.shape[1:3]
    extrinsics, intrinsics = vggt_pose_encoding_to_cameras(pose_enc, processed)
    world_points, conf = None, depth_conf
    if config.points_from == "point_head":
        world_points = _unbatch(get("world_points"), 4) if get("world_points") is not None else None
        if get("world_points_conf") is not None:
            conf = _unbatch(get("world_points_conf"), 3)
    return depth_maps_to_shared_space(depth, conf, extrinsics, intrinsics, image_size, cut_frame, "vggt", config,
                                      world_points)


def da3_outputs_to_shared_space(outputs: dict, image_size: tuple[int, int], cut_frame: int,
                                config: LearnedSpaceConfig = LearnedSpaceConfig()) -> SharedSpace:
    """Depth-Anything-3's outputs (network dict with a batch axis, or its ``Prediction`` fields) to a space."""
    get = lambda *keys: next((_numpy(outputs[k]) for k in keys if outputs.get(k) is not None), None)
    depth, conf = get("depth"), get("depth_conf", "conf")
    extrinsics, intrinsics = get("extrinsics"), get("intrinsics")
    if depth is None or conf is None or extrinsics is None or intrinsics is None:
        raise InputError("Depth-Anything-3 outputs: need depth, conf (depth_conf), extrinsics and intrinsics "
                         "(a model without a camera head cannot build a shared space)")
    depth = _unbatch(depth, 3)
    return depth_maps_to_shared_space(depth, _unbatch(conf, 3), _unbatch(extrinsics, 3), _unbatch(intrinsics, 3),
                                      image_size, cut_frame, "depth_anything_3", config)


def _numpy(value) -> np.ndarray:
    if hasattr(value, "detach"):
        value = value.detach().cpu().double().numpy()
    return np.asarray(value)


def _unbatch(arr: np.ndarray, ndim: int) -> np.ndarray:
    """Drop a leading batch axis of size one when the array has one more axis than ``ndim``."""
    arr = np.asarray(arr)
    if arr.ndim == ndim + 1 and arr.shape[0] == 1:
        return arr[0]
    if arr.ndim == ndim + 2 and arr.shape[0] == 1 and arr.shape[-1] == 1:  # depth (1, S, H, W, 1)
        return arr[0]
    return arr


# ----------------------------------------------------------------------------------------------------
# Loading and running


def _weights_path(path, what: str) -> Path:
    if path is None:
        raise InputError(f"{what}: no weights given (a local folder or file; nothing is downloaded)")
    path = Path(path).expanduser()
    if not path.exists():
        raise InputError(f"{path}: no such {what} weights (a local folder or file; nothing is downloaded)")
    return path


def _load_state(path: Path) -> dict:
    import torch

    if path.suffix == ".safetensors":
        from safetensors.torch import load_file

        return load_file(str(path))
    try:
        state = torch.load(str(path), map_location="cpu", weights_only=True)
    except Exception as exc:
        raise InputError(f"{path}: not a readable weights file ({exc.__class__.__name__})") from None
    return state.get("model", state) if isinstance(state, dict) else state


def load_vggt(weights, device: str = "cpu"):
    """A VGGT model from a local folder (``config.json`` + weights, as ``VGGT.from_pretrained`` saves) or file.

    Raises :class:`InputError` when the ``vggt`` package is missing or the weights do not load.
    """
    path = _weights_path(weights, "VGGT")
    try:
        from vggt.models.vggt import VGGT
    except ImportError:
        raise InputError("vggt backend: the 'vggt' package is not installed (install it from its "
                         "GitHub repository)") from None
    if path.is_dir():
        model = VGGT.from_pretrained(str(path), local_files_only=True)
    else:
        model = VGGT()
        missing, _ = model.load_state_dict(_load_state(path), strict=False)
        if missing:
            raise InputError(f"{path}: not VGGT weights ({len(missing)} parameters missing, e.g. {missing[0]})")
    return model.eval().to(device)


def _frames_pair(frame_a: np.ndarray, frame_b: np.ndarray) -> np.ndarray:
    frames = np.stack([np.asarray(frame_a), np.asarray(frame_b)])
    if frames.ndim != 4 or frames.shape[-1] != 3 or frames.dtype != np.uint8:
        raise InputError(f"frames: expected two (H, W, 3) uint8 RGB frames of one size, got {frames.shape} "
                         f"{frames.dtype}")
    return frames


def vggt_shared_space(model, frame_a: np.ndarray, frame_b: np.ndarray, cut_frame: int,
                      config: LearnedSpaceConfig = LearnedSpaceConfig()) -> SharedSpace:
    """Run VGGT on the two boundary frames and convert its output (width 518, height a multiple of 14)."""
    import torch

    frames = _frames_pair(frame_a, frame_b)
    H, W = frames.shape[1:3]
    h = max(PATCH, int(round(H * VGGT_WIDTH / W / PATCH)) * PATCH)
    resized = np.stack([cv2.resize(f, (VGGT_WIDTH, h), interpolation=cv2.INTER_AREA) for f in frames])
    images = torch.from_numpy(resized).permute(0, 3, 1, 2).float().div(255.0).to(config.device)
    with torch.no_grad():
        predictions = model(images)
    return vggt_outputs_to_shared_space(predictions, (H, W), cut_frame, config)


class DA3Network:
    """A Depth-Anything-3 network built from the package's config registry, weights loaded from a local folder."""

    def __init__(self, net, model_name: str, device: str = "cpu"):
        self.net = net.eval().to(device)
        self.model_name = model_name
        self.device = device

    def __call__(self, images):
        import torch

        with torch.no_grad():
            return self.net(images)


def build_da3_network(model_name: str):
    """An untrained Depth-Anything-3 network of a named preset (``da3-small``, ``da3-base``...), no download."""
    try:
        from depth_anything_3.cfg import create_object, load_config
        from depth_anything_3.registry import MODEL_REGISTRY
    except ImportError:
        from multithumbs.extras import missing_package_message

        raise InputError(missing_package_message("depth_anything_3", "the depth-anything-3 backend")) from None
    if model_name not in MODEL_REGISTRY:
        raise InputError(f"Depth-Anything-3 model {model_name!r}: unknown; known: {', '.join(MODEL_REGISTRY)}")
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return create_object(load_config(MODEL_REGISTRY[model_name]))


def load_da3(weights, device: str = "cpu") -> DA3Network:
    """Depth-Anything-3 from a local folder holding ``config.json`` (``model_name``) and ``model.safetensors``.

    This is the layout ``DepthAnything3.save_pretrained`` writes and the hub's model folders have; the
    state dict's ``model.`` prefix (the API wrapper's attribute) is stripped.
    """
    path = _weights_path(weights, "Depth-Anything-3")
    if not path.is_dir():
        raise InputError(f"{path}: expected a Depth-Anything-3 model folder (config.json + model.safetensors)")
    config_file, weights_file = path / "config.json", path / "model.safetensors"
    for needed in (config_file, weights_file):
        if not needed.is_file():
            raise InputError(f"{path}: missing {needed.name} (a Depth-Anything-3 model folder)")
    try:
        model_name = json.loads(config_file.read_text()).get("model_name", "da3-large")
    except (json.JSONDecodeError, AttributeError):
        raise InputError(f"{config_file}: not a JSON object with a model_name") from None
    net = build_da3_network(model_name)
    state = {k.removeprefix("model."): v for k, v in _load_state(weights_file).items()}
    missing, _ = net.load_state_dict(state, strict=False)
    if missing:
        raise InputError(f"{weights_file}: does not fit {model_name} ({len(missing)} parameters missing, "
                         f"e.g. {missing[0]})")
    return DA3Network(net, model_name, device)


def da3_input(frames: np.ndarray, process_res: int) -> np.ndarray:
    """ImageNet-normalised ``(1, N, 3, h, w)`` float32 input, longer side at most ``process_res``, sides
    multiples of 14 (the package's ``upper_bound_resize``)."""
    H, W = frames.shape[1:3]
    scale = process_res / max(H, W)
    h = max(PATCH, int(round(H * scale / PATCH)) * PATCH)
    w = max(PATCH, int(round(W * scale / PATCH)) * PATCH)
    resized = np.stack([cv2.resize(f, (w, h), interpolation=cv2.INTER_AREA) for f in frames]).astype(np.float32)
    normalised = (resized / 255.0 - IMAGENET_MEAN) / IMAGENET_STD
    return normalised.transpose(0, 3, 1, 2)[None].astype(np.float32)


def da3_shared_space(model: DA3Network, frame_a: np.ndarray, frame_b: np.ndarray, cut_frame: int,
                     config: LearnedSpaceConfig = LearnedSpaceConfig()) -> SharedSpace:
    """Run Depth-Anything-3 on the two boundary frames (its camera head gives the poses) and convert."""
    import torch

    frames = _frames_pair(frame_a, frame_b)
    images = torch.from_numpy(da3_input(frames, config.process_res)).to(model.device)
    outputs = model(images)
    return da3_outputs_to_shared_space(dict(outputs), frames.shape[1:3], cut_frame, config)
