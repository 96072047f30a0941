"""2D keypoints with ViTPose and masks with SAM through ``transformers``, for the boxes of existing tracks.

Weights come from a local folder or the Hugging Face cache only (``local_files_only=True``): nothing is
downloaded at run time. A model argument is a folder written by ``save_pretrained`` (with its processor
config) or a hub name already in the cache (e.g. ``usyd-community/vitpose-base-simple``,
``facebook/sam-vit-base``).

* :class:`VitPoseEstimator` — ``VitPoseForPoseEstimation`` on each person box (COCO ``x, y, w, h``),
  ``post_process_pose_estimation`` to image pixels, COCO-17 mapped to SMPL-24 (:mod:`.joints`). ViTPose++
  (mixture-of-experts) checkpoints get ``dataset_index = 0`` (COCO).
* :class:`SamSegmenter` — ``SamModel`` prompted by each box (``input_boxes``, one mask per box,
  ``multimask_output=False``), ``post_process_masks`` back to the image.

:func:`refine_tracks` runs them over a video once per shot and replaces ``keypoints2d`` and/or ``masks`` of
every valid (track, frame).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Sequence

import numpy as np

from multithumbs.errors import InputError
from multithumbs.perception.joints import coco17_to_smpl24
from multithumbs.types import PersonTracks, pack_mask


def _pretrained(kind: str, loader, model: str | Path):
    """``loader.from_pretrained(model, local_files_only=True)`` with a one-line error when it is not local."""
    try:
        return loader.from_pretrained(str(model), local_files_only=True)
    except (OSError, ValueError) as exc:
        first = str(exc).splitlines()[0][:160] if str(exc) else exc.__class__.__name__
        raise InputError(f"{kind} model {str(model)!r}: not loadable from a local folder or the Hugging Face "
                         f"cache (weights are never downloaded at run time): {first}") from None


def _boxes_ok(boxes: np.ndarray) -> np.ndarray:
    b = np.asarray(boxes, dtype=np.float64)
    return np.isfinite(b).all(-1) & (b[..., 2] - b[..., 0] >= 2) & (b[..., 3] - b[..., 1] >= 2)


class VitPoseEstimator:
    """A loaded ViTPose model: ``__call__(frame, boxes_xyxy) -> (N, 24, 3)`` SMPL-order keypoints."""

    def __init__(self, model: str | Path, device: str = "cpu"):
        import torch
        from transformers import AutoImageProcessor, VitPoseForPoseEstimation

        self.processor = _pretrained("ViTPose", AutoImageProcessor, model)
        self.model = _pretrained("ViTPose", VitPoseForPoseEstimation, model).to(device).eval()
        self.device = device
        self.num_keypoints = int(self.model.config.num_labels)
        if self.num_keypoints != 17:
            raise InputError(f"ViTPose model {str(model)!r}: predicts {self.num_keypoints} keypoints, expected "
                             f"the 17 COCO keypoints")
        experts = getattr(self.model.config.backbone_config, "num_experts", 1)
        self._dataset_index = torch.zeros(1, dtype=torch.long) if experts > 1 else None

    def coco_keypoints(self, frame: np.ndarray, boxes_xyxy: np.ndarray) -> np.ndarray:
        """``(N, 17, 3)`` COCO keypoints ``u, v, score`` in ``N`` boxes, in the boxes' pixel coordinates."""
        import torch

        boxes = np.asarray(boxes_xyxy, dtype=np.float64).reshape(-1, 4)
        if len(boxes) == 0:
            return np.zeros((0, 17, 3))
        coco = np.concatenate([boxes[:, :2], boxes[:, 2:] - boxes[:, :2]], axis=1)
        inputs = self.processor(images=[frame], boxes=[coco.tolist()], return_tensors="pt")
        kwargs = {"pixel_values": inputs["pixel_values"].to(self.device)}
        if self._dataset_index is not None:
            kwargs["dataset_index"] = self._dataset_index.expand(len(boxes)).to(self.device)
        with torch.no_grad():
            outputs = self.model(**kwargs)
        results = self.processor.post_process_pose_estimation(outputs, boxes=[coco.tolist()])[0]
        out = np.zeros((len(boxes), 17, 3))
        for n, person in enumerate(results):
            out[n, :, :2] = person["keypoints"].cpu().numpy()  # in the boxes' pixel frame
            out[n, :, 2] = np.clip(person["scores"].cpu().numpy().reshape(-1), 0.0, 1.0)
        return out

    def __call__(self, frame: np.ndarray, boxes_xyxy: np.ndarray) -> np.ndarray:
        return coco17_to_smpl24(self.coco_keypoints(frame, boxes_xyxy))


class SamSegmenter:
    """A loaded SAM model: ``__call__(frame, boxes_xyxy) -> (N, H, W)`` bool masks, one per box."""

    def __init__(self, model: str | Path, device: str = "cpu"):
        from transformers import AutoProcessor, SamModel

        self.processor = _pretrained("SAM", AutoProcessor, model)
        self.model = _pretrained("SAM", SamModel, model).to(device).eval()
        self.device = device

    def __call__(self, frame: np.ndarray, boxes_xyxy: np.ndarray) -> np.ndarray:
        import torch

        boxes = np.asarray(boxes_xyxy, dtype=np.float64).reshape(-1, 4)
        h, w = frame.shape[:2]
        if len(boxes) == 0:
            return np.zeros((0, h, w), bool)
        inputs = self.processor(images=[frame], input_boxes=[boxes.tolist()], return_tensors="pt")
        model_inputs = {k: inputs[k].to(self.device) for k in ("pixel_values", "input_boxes")}
        with torch.no_grad():
            outputs = self.model(**model_inputs, multimask_output=False)
        masks = self.processor.image_processor.post_process_masks(
            outputs.pred_masks.cpu(), inputs["original_sizes"], inputs["reshaped_input_sizes"])[0]
        return masks[:, 0].numpy().astype(bool).reshape(len(boxes), h, w)


def load_vitpose(model: str | Path, device: str = "cpu") -> VitPoseEstimator:
    """A ViTPose estimator from a local folder or cached hub name (module docstring)."""
    return VitPoseEstimator(model, device)


def load_sam(model: str | Path, device: str = "cpu") -> SamSegmenter:
    """A SAM segmenter from a local folder or cached hub name (module docstring)."""
    return SamSegmenter(model, device)


def refine_tracks(tracks: Sequence[PersonTracks], boxes: Sequence[np.ndarray], video,
                  keypoints=None, segmenter=None, progress=None) -> list[PersonTracks]:
    """Replace keypoints (``keypoints(frame, boxes) -> (N, 24, 3)``) and/or masks
    (``segmenter(frame, boxes) -> (N, H, W)``) of every valid (track, frame) whose box is usable.

    Args:
        tracks: per shot :class:`PersonTracks`.
        boxes: per shot ``(P, T, 4)`` ``x0, y0, x1, y1`` boxes.
        video: the video file or its frames ``(T, H, W, 3)``.
        keypoints: a keypoint estimator (e.g. :class:`VitPoseEstimator`) or None.
        segmenter: a mask estimator (e.g. :class:`SamSegmenter`) or None.
        progress: optional ``callable(done_frames, total_frames)``.
    """
    from multithumbs.perception.appearance import _frames

    if len(boxes) != len(tracks):
        raise InputError(f"boxes: {len(boxes)} box sets for {len(tracks)} shots of tracks")
    total = sum(tr.num_frames for tr in tracks)
    out, done = [], 0
    for k, (tr, box) in enumerate(zip(tracks, boxes)):
        if box.shape[:2] != tr.valid.shape:
            raise InputError(f"shot {k}: boxes {box.shape[:2]} do not match the tracks {tr.valid.shape}")
        kp = tr.keypoints2d.copy() if keypoints is not None else tr.keypoints2d
        if keypoints is not None and kp.shape[2] != 24:
            kp = np.zeros((*tr.valid.shape, 24, 3))
        masks = tr.masks.copy()
        usable = tr.valid & _boxes_ok(box)
        seen = 0
        for j, frame in enumerate(_frames(video, tr.start_frame, tr.start_frame + tr.num_frames)):
            seen = j + 1
            people = np.nonzero(usable[:, j])[0]
            if len(people):
                if keypoints is not None:
                    kp[people, j] = keypoints(frame, box[people, j])
                if segmenter is not None:
                    masks[people, j] = pack_mask(segmenter(frame, box[people, j]))
            if progress:
                progress(done + seen, total)
        if seen < tr.num_frames:
            raise InputError(f"video: ends at frame {tr.start_frame + seen} but shot {k}'s tracks run to frame "
                             f"{tr.start_frame + tr.num_frames - 1}")
        done += tr.num_frames
        out.append(dataclasses.replace(tr, keypoints2d=kp, masks=masks))
    return out
