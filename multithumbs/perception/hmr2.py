"""HMR2 (4DHumans) run directly on the video, when the ``hmr2`` package is installed.

The real path follows 4DHumans' ``demo.py``: ``hmr2.models.load_hmr2(checkpoint)``; people detected per
frame by detectron2's ViTDet cascade Mask R-CNN with the config shipped in ``hmr2/configs`` and LOCAL
detector weights (``detector=PATH``; the demo's URL is never fetched); crops through
``hmr2.datasets.vitdet_dataset.ViTDetDataset``; the model's outputs converted by
:func:`hmr2_outputs_to_people`. Detections are linked into tracks within each shot by box overlap
(:func:`link_boxes`, Hungarian on IoU) — a plain tracker standing in for PHALP's, which needs its own
weights; import PHALP's results (``phalp:``) for its tracks.

HMR2's documented outputs (``HMR2.forward_step``): ``pred_smpl_params`` with ``global_orient (B, 1, 3, 3)``,
``body_pose (B, 23, 3, 3)``, ``betas (B, 10)``; ``pred_cam (B, 3)`` weak-perspective ``(s, tx, ty)`` on the
crop; ``pred_keypoints_2d (B, 44, 2)`` projected joints in crop units (``(x + 0.5) * 256`` is the crop
pixel), OpenPose BODY_25 first; ``focal_length (B, 2)``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Sequence

import numpy as np
from scipy.optimize import linear_sum_assignment
from scipy.spatial.transform import Rotation

from multithumbs.appearance import DESCRIPTOR_SIZE
from multithumbs.errors import InputError
from multithumbs.perception import HMR2_INSTALL_HINT  # one text for this and the CLI's early check
from multithumbs.perception.camera import (
    HMR2_CROP_SIZE,
    HMR2_FOCAL_LENGTH,
    cam_crop_to_full,
    hmr2_focal_length,
    hmr2_intrinsics,
)
from multithumbs.perception.joints import openpose25_to_smpl24
from multithumbs.types import PersonTracks, Shots, pack_mask

INSTALL_HINT = HMR2_INSTALL_HINT


def require_hmr2() -> Any:
    """The ``hmr2`` module, or :class:`InputError` saying how to get it."""
    try:
        import hmr2
    except ImportError:
        raise InputError(f"perception backend 'hmr2': the hmr2 package is not installed; {INSTALL_HINT}") from None
    return hmr2


DEVICE_AUTO = "auto"
"""Device choice meaning CUDA when present, else CPU."""


def select_device(requested: str | None = DEVICE_AUTO, cuda_available: bool | None = None) -> str:
    """The torch device for the learned backends: CUDA when present for ``"auto"``, else what was asked.

    ``cuda_available`` defaults to ``torch.cuda.is_available()`` (a parameter so tests need no GPU).

    Raises:
        InputError: CUDA asked for on a machine without it, or a device name torch does not know.
    """
    import torch

    cuda = torch.cuda.is_available() if cuda_available is None else bool(cuda_available)
    name = (requested or DEVICE_AUTO).strip().lower()
    if name == DEVICE_AUTO:
        return "cuda" if cuda else "cpu"
    try:
        kind = torch.device(name).type
    except RuntimeError:
        raise InputError(f"--device {requested!r}: not a torch device (auto, cpu, cuda, cuda:N)") from None
    if kind == "cuda" and not cuda:
        raise InputError(f"--device {requested!r}: CUDA is not available on this machine "
                         f"(torch.cuda.is_available() is False); use --device cpu or auto")
    return name


def load_hmr2_model(checkpoint: str | Path) -> tuple[Any, Any]:
    """HMR2's ``(model, cfg)`` WITHOUT its mesh renderer, which needs EGL/OpenGL even for inference.

    ``hmr2.models.load_hmr2`` builds the model with ``init_renderer=True`` (a pyrender ``Renderer``); the
    ``HMR2`` class takes ``init_renderer=False``, so the model is built from its config and checkpoint that
    way (the config is ``model_config.yaml`` two folders above the checkpoint, as ``load_hmr2`` finds it).
    Checked against 4D-Humans at commit 068130a: ``hmr2/models/hmr2.py`` (``HMR2.__init__(cfg,
    init_renderer=True)``) and ``hmr2/models/__init__.py`` (``load_hmr2``: ``get_config(...,
    update_cachedir=True)``, the ViT ``BBOX_SHAPE`` override, ``load_from_checkpoint(..., strict=False)``).
    An hmr2 without that switch falls back to ``load_hmr2``; if that fails for want of a renderer the
    message says what is missing.

    Raises:
        InputError: the checkpoint or its config is missing, or the renderer cannot be built.
    """
    checkpoint = Path(checkpoint)
    config = checkpoint.parent.parent / "model_config.yaml"
    if not checkpoint.is_file():
        raise InputError(f"perception backend 'hmr2': checkpoint {checkpoint} not found; {INSTALL_HINT}")
    try:
        from hmr2.configs import get_config
        from hmr2.models import HMR2
    except ImportError as exc:
        raise InputError(f"perception backend 'hmr2': cannot import hmr2.models/hmr2.configs ({exc}); "
                         f"{INSTALL_HINT}") from None
    if not config.is_file():
        raise InputError(f"perception backend 'hmr2': {config} not found (HMR2 keeps its model_config.yaml two "
                         f"folders above the checkpoint)")
    cfg = get_config(str(config), update_cachedir=True)
    if cfg.MODEL.BACKBONE.TYPE == "vit" and "BBOX_SHAPE" not in cfg.MODEL:
        # Released ViT checkpoints predate BBOX_SHAPE; HMR2's crops are 192x256 (what load_hmr2 also sets).
        cfg.defrost()
        cfg.MODEL.BBOX_SHAPE = [192, 256]
        cfg.freeze()
    try:
        model = HMR2.load_from_checkpoint(str(checkpoint), strict=False, cfg=cfg, init_renderer=False)
        return model, cfg
    except TypeError:
        pass  # an hmr2 without init_renderer: only load_hmr2's path is left
    from hmr2.models import load_hmr2

    try:
        return load_hmr2(str(checkpoint))
    except (ImportError, OSError, RuntimeError, AttributeError) as exc:
        text = f"{exc.__class__.__name__}: {str(exc).splitlines()[0][:120] if str(exc) else ''}"
        if any(word in text.lower() for word in ("egl", "opengl", "pyrender", "display", "glx")):
            raise InputError(f"perception backend 'hmr2': load_hmr2 builds a mesh renderer that needs EGL/OpenGL "
                             f"and it failed ({text}); install libEGL and set PYOPENGL_PLATFORM=egl, or use an "
                             f"hmr2 whose HMR2 takes init_renderer=False") from None
        raise


def detector_predictor(cfg: Any, device: str) -> Any:
    """4D-Humans' ViTDet predictor on ``device``.

    Its detectron2 wrapper (``hmr2/utils/utils_detectron2.py``) moves the detector to CUDA whatever the
    device; on a machine without CUDA that fails inside the wrapper, and this says so in one line. On a CUDA
    machine the detector is then moved to ``device``.
    """
    from hmr2.utils.utils_detectron2 import DefaultPredictor_Lazy

    try:
        predictor = detector_predictor(cfg, device)
    except (AssertionError, RuntimeError) as exc:
        if "cuda" not in str(exc).lower() and "nvidia" not in str(exc).lower():
            raise
        raise InputError("perception backend 'hmr2': 4D-Humans' detectron2 wrapper (hmr2/utils/utils_detectron2.py)"
                         " puts the ViTDet detector on CUDA and this machine has none; run on a CUDA machine, or "
                         "import 4DHumans results with phalp:RESULTS.pkl") from None
    predictor.model.to(device)
    return predictor


def _np(x: Any) -> np.ndarray:
    if hasattr(x, "detach"):
        x = x.detach().cpu().numpy()
    return np.asarray(x, dtype=np.float64)


def hmr2_outputs_to_people(outputs: dict, box_center: np.ndarray, box_size: np.ndarray,
                           image_size: tuple[int, int], focal_length: float = HMR2_FOCAL_LENGTH,
                           crop_size: int = HMR2_CROP_SIZE) -> dict[str, np.ndarray]:
    """HMR2's outputs for ``B`` crops to camera-frame SMPL parameters and SMPL-order 2D keypoints.

    Args:
        outputs: HMR2's output dict (module docstring), tensors or arrays.
        box_center: ``(B, 2)`` crop centres (HMR2's continuous pixels, the batch's ``box_center``).
        box_size: ``(B,)`` crop sides in pixels (``box_size``).
        image_size: ``(H, W)``.
        focal_length, crop_size: HMR2's ``EXTRA.FOCAL_LENGTH`` and ``MODEL.IMAGE_SIZE``.
    Returns:
        ``global_orient (B, 3)``, ``body_pose (B, 23, 3)`` axis-angle, ``betas (B, 10)``, ``transl (B, 3)``
        for the intrinsics ``K (3, 3)`` (also returned; :func:`hmr2_intrinsics` without square padding),
        ``keypoints2d (B, 24, 3)`` in integer-centred pixels with confidence 1 for the SMPL joints HMR2's
        OpenPose joints are (0 for the others and outside the image): ``pred_keypoints_3d`` projected with
        ``K`` when present, else ``pred_keypoints_2d`` mapped from the crop.
    """
    params = outputs["pred_smpl_params"]
    orient = _np(params["global_orient"])
    b = orient.shape[0]
    orient = Rotation.from_matrix(orient.reshape(b, 3, 3)).as_rotvec()
    pose = Rotation.from_matrix(_np(params["body_pose"]).reshape(b * 23, 3, 3)).as_rotvec().reshape(b, 23, 3)
    betas = _np(params["betas"]).reshape(b, -1)[:, :10]
    h, w = image_size
    f = hmr2_focal_length((h, w), focal_length, crop_size)
    centre, size = _np(box_center).reshape(b, 2), _np(box_size).reshape(b)
    transl = cam_crop_to_full(_np(outputs["pred_cam"]).reshape(b, 3), centre, size, (h, w), f)
    K = hmr2_intrinsics((h, w), focal_length, crop_size, padded_square=False)
    if "pred_keypoints_3d" in outputs:
        # The joints in the full-image camera: exact for every joint, not only at the root's depth.
        uvw = (_np(outputs["pred_keypoints_3d"]).reshape(b, -1, 3) + transl[:, None]) @ K.T
        pixels = uvw[..., :2] / uvw[..., 2:]
    else:
        kp = _np(outputs["pred_keypoints_2d"]).reshape(b, -1, 2)
        pixels = centre[:, None] + kp * size[:, None, None] - 0.5  # crop units -> continuous pixels -> ours
    smpl = openpose25_to_smpl24(np.concatenate([pixels, np.ones((*pixels.shape[:2], 1))], axis=-1))
    inside = (smpl[..., 0] >= -0.5) & (smpl[..., 0] < w - 0.5) & (smpl[..., 1] >= -0.5) & (smpl[..., 1] < h - 0.5)
    smpl[..., 2] *= inside
    return {"global_orient": orient, "body_pose": pose, "betas": betas, "transl": transl, "keypoints2d": smpl, "K": K}


def box_iou(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``(N, M)`` intersection over union of boxes ``a (N, 4)`` and ``b (M, 4)`` (``x0, y0, x1, y1``)."""
    a, b = np.asarray(a, float).reshape(-1, 4), np.asarray(b, float).reshape(-1, 4)
    lo = np.maximum(a[:, None, :2], b[None, :, :2])
    hi = np.minimum(a[:, None, 2:], b[None, :, 2:])
    inter = np.prod(np.clip(hi - lo, 0, None), axis=-1)
    area = lambda x: np.prod(np.clip(x[:, 2:] - x[:, :2], 0, None), axis=-1)
    return inter / np.maximum(area(a)[:, None] + area(b)[None] - inter, 1e-12)


def link_boxes(boxes: Sequence[np.ndarray], min_iou: float = 0.3, max_gap: int = 5) -> list[np.ndarray]:
    """Track ids for per-frame detections: Hungarian matching on IoU with each track's last box.

    Args:
        boxes: per frame ``(N_t, 4)`` boxes.
        min_iou: a detection joins a track only above this overlap.
        max_gap: frames a track may go undetected before it ends.
    Returns:
        per frame ``(N_t,)`` int track ids from 0.
    """
    ids, live = [], {}  # live: id -> (last box, last frame)
    next_id = 0
    for t, frame_boxes in enumerate(boxes):
        frame_boxes = np.asarray(frame_boxes, float).reshape(-1, 4)
        live = {k: v for k, v in live.items() if t - v[1] <= max_gap}
        keys = list(live)
        out = np.full(len(frame_boxes), -1, np.int64)
        if keys and len(frame_boxes):
            iou = box_iou(np.stack([live[k][0] for k in keys]), frame_boxes)
            rows, cols = linear_sum_assignment(-iou)
            for r, c in zip(rows, cols):
                if iou[r, c] >= min_iou:
                    out[c] = keys[r]
        for c in range(len(frame_boxes)):
            if out[c] < 0:
                out[c], next_id = next_id, next_id + 1
            live[int(out[c])] = (frame_boxes[c], t)
        ids.append(out)
    return ids


def assemble_tracks(shots: Shots, image_size: tuple[int, int], K: np.ndarray, detections: Sequence[dict],
                    min_iou: float = 0.3) -> tuple[list[PersonTracks], list[np.ndarray]]:
    """Per-frame people (``boxes (N, 4)``, ``masks (N, H, W)`` and :func:`hmr2_outputs_to_people`'s arrays)
    linked into per-shot :class:`PersonTracks` (and their boxes); tracks never cross a cut."""
    h, w = image_size
    tracks, all_boxes = [], []
    for shot, (a, b) in enumerate(shots.ranges):
        ids = link_boxes([detections[f]["boxes"] for f in range(a, b)], min_iou)
        p, t = max((int(i.max()) + 1 for i in ids if len(i)), default=0), b - a
        arrays = {"global_orient": np.zeros((p, t, 3)), "body_pose": np.zeros((p, t, 23, 3)),
                  "transl": np.zeros((p, t, 3)), "keypoints2d": np.zeros((p, t, 24, 3))}
        betas_sum, valid = np.zeros((p, 10)), np.zeros((p, t), bool)
        masks, boxes = np.zeros((p, t, h, (w + 7) // 8), np.uint8), np.zeros((p, t, 4))
        for j, frame_ids in enumerate(ids):
            det = detections[a + j]
            for n, i in enumerate(frame_ids):
                for key in arrays:
                    arrays[key][i, j] = det[key][n]
                betas_sum[i] += det["betas"][n]
                valid[i, j] = True
                boxes[i, j] = det["boxes"][n]
                if det.get("masks") is not None:
                    masks[i, j] = pack_mask(det["masks"][n])
        tracks.append(PersonTracks(
            shot_index=shot, start_frame=a, track_ids=np.arange(p), betas=betas_sum / np.maximum(valid.sum(1), 1)[:, None],
            masks=masks, image_size=(h, w), K=K, appearance=np.zeros((p, t, DESCRIPTOR_SIZE)),
            appearance_valid=np.zeros((p, t), bool), valid=valid, **arrays))
        all_boxes.append(boxes)
    return tracks, all_boxes


def run_hmr2(video: str | Path, shots: Shots, checkpoint: str | None = None, detector: str | None = None,
             device: str = DEVICE_AUTO, min_score: float = 0.5, batch_size: int = 8,
             progress=None) -> tuple[list[PersonTracks], list[np.ndarray]]:
    """HMR2 on every frame of ``video`` (module docstring); per-shot tracks and boxes.

    Args:
        video: the video file.
        shots: its shots.
        checkpoint: HMR2 checkpoint (``.ckpt`` with ``model_config.yaml`` two folders up); default
            ``hmr2.models.DEFAULT_CHECKPOINT`` in 4DHumans' cache.
        detector: local ViTDet weights (``model_final_f05665.pkl``) for detectron2.
        device: torch device, or ``"auto"``: CUDA when present (:func:`select_device`).
        min_score: person detection threshold (the demo's 0.5).
    """
    require_hmr2()
    import torch

    try:
        import detectron2  # noqa: F401
    except ImportError:
        raise InputError("perception backend 'hmr2': detectron2 is not installed (4DHumans detects people with "
                         "its ViTDet model); install it, or import 4DHumans results with phalp:RESULTS.pkl") from None
    if detector is None or not Path(detector).is_file():
        raise InputError(f"perception backend 'hmr2': detector weights {detector!r} not found; pass the local "
                         f"ViTDet checkpoint as hmr2:detector=PATH (weights are never downloaded at run time)")
    import hmr2
    from detectron2.config import LazyConfig
    from hmr2.datasets.vitdet_dataset import ViTDetDataset
    from hmr2.models import DEFAULT_CHECKPOINT
    from hmr2.utils import recursive_to

    from multithumbs.video import iter_frames, probe_video

    device = select_device(device)
    model, model_cfg = load_hmr2_model(checkpoint or DEFAULT_CHECKPOINT)
    model = model.to(device).eval()
    cfg = LazyConfig.load(str(Path(hmr2.__file__).parent / "configs" / "cascade_mask_rcnn_vitdet_h_75ep.py"))
    cfg.train.init_checkpoint = str(detector)
    for i in range(3):
        cfg.model.roi_heads.box_predictors[i].test_score_thresh = 0.25
    predictor = detector_predictor(cfg, device)
    info = probe_video(video)
    if info.num_frames != shots.num_frames:
        raise InputError(f"{video}: {info.num_frames} frames but the shots cover {shots.num_frames}")
    h, w = info.image_size
    detections = []
    for t, rgb in enumerate(iter_frames(video)):
        bgr = np.ascontiguousarray(rgb[:, :, ::-1])
        instances = predictor(bgr)["instances"]
        keep = (instances.pred_classes == 0) & (instances.scores > min_score)
        boxes = instances.pred_boxes.tensor[keep].cpu().numpy()
        masks = instances.pred_masks[keep].cpu().numpy() if instances.has("pred_masks") else None
        people: dict[str, list] = {k: [] for k in ("global_orient", "body_pose", "betas", "transl", "keypoints2d")}
        loader = torch.utils.data.DataLoader(ViTDetDataset(model_cfg, bgr, boxes), batch_size=batch_size,
                                             shuffle=False, num_workers=0)
        for batch in loader:
            batch = recursive_to(batch, device)
            with torch.no_grad():
                out = model(batch)
            conv = hmr2_outputs_to_people(out, batch["box_center"], batch["box_size"], (h, w),
                                          model_cfg.EXTRA.FOCAL_LENGTH, model_cfg.MODEL.IMAGE_SIZE)
            for key in people:
                people[key].extend(conv[key])
        detections.append({"boxes": boxes - np.array([0.5, 0.5, 0.5, 0.5]), "masks": masks,
                           **{k: np.asarray(v) for k, v in people.items()}})
        if progress:
            progress(t + 1, shots.num_frames)
    K = hmr2_intrinsics((h, w), model_cfg.EXTRA.FOCAL_LENGTH, model_cfg.MODEL.IMAGE_SIZE, padded_square=False)
    return assemble_tracks(shots, (h, w), K, detections)
