"""BlazePose's two models run the way MediaPipe's pose graph runs them, without MediaPipe.

MediaPipe's own Python package pins numpy<2 and protobuf<5, which the project cannot take, so the two
``.tflite`` files of its 0.10.21 wheel (:mod:`.blazepose_models`) run here under ``ai_edge_litert`` and
the graph's pre- and post-processing is written out below. Each step names the MediaPipe graph or
calculator it follows (paths in google-ai-edge/mediapipe):

* detection (``modules/pose_detection/pose_detection_cpu.pbtxt``): the frame letterboxed to 224x224 in
  [-1, 1]; 2254 SSD anchors (``SsdAnchorsCalculator``: 5 layers, strides 8, 16, 32, 32, 32, fixed size);
  boxes and 4 keypoints decoded against them (``TensorsToDetectionsCalculator``, x before y); sigmoid
  scores ≥ 0.2; weighted non-maximum suppression at IoU 0.3; letterbox removed. The box is the face;
  keypoints 0–3 are the mid-hip, a point giving the full body's size and tilt, the mid-shoulder and the
  upper body's point.
* the region of interest (``modules/pose_landmark/pose_detection_to_roi.pbtxt`` and
  ``pose_landmarks_to_roi.pbtxt``): a square centred on one alignment point, its side 2 × 1.5 × the
  distance to the other, turned so that the second point is straight above the first.
* landmarks (``pose_landmark_by_roi_cpu.pbtxt``, ``tensors_to_pose_landmarks_and_segmentation.pbtxt``):
  the rotated square warped to 256x256 in [0, 1]; 39 landmarks of x, y, z, visibility, presence (sigmoid
  on the last two), refined from the 64x64 heatmap (``RefineLandmarksFromHeatmapCalculator``, 7x7 window,
  confidence ≥ 0.5); projected back through the square; world landmarks (metres, origin between the hips)
  turned by the square's rotation; the segmentation's sigmoid warped back onto the frame. The pose flag
  is already a probability (the graph thresholds it at 0.5 without an activation).

Landmarks 0–32 are BlazePose's topology (:data:`LANDMARK_NAMES`); 33 and 34 are the auxiliary points the
next frame's square is built from. Pixel coordinates follow :mod:`multithumbs.conventions`.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

DETECTOR_SIZE = 224
LANDMARK_SIZE = 256
NUM_LANDMARKS = 39
NUM_POSE_LANDMARKS = 33
HEATMAP_KERNEL = 7
REFINE_MIN_CONFIDENCE = 0.5
ROI_SCALE = 1.25
MIN_DETECTION_SCORE = 0.2
NMS_IOU = 0.3

LANDMARK_NAMES: tuple[str, ...] = (
    "nose", "left_eye_inner", "left_eye", "left_eye_outer", "right_eye_inner", "right_eye", "right_eye_outer",
    "left_ear", "right_ear", "mouth_left", "mouth_right", "left_shoulder", "right_shoulder", "left_elbow",
    "right_elbow", "left_wrist", "right_wrist", "left_pinky", "right_pinky", "left_index", "right_index",
    "left_thumb", "right_thumb", "left_hip", "right_hip", "left_knee", "right_knee", "left_ankle",
    "right_ankle", "left_heel", "right_heel", "left_foot_index", "right_foot_index",
)
"""BlazePose's 33 pose landmarks in model order (the person's left and right)."""


@dataclass(frozen=True)
class Detection:
    """One person found by the detector, in frame pixels.

    Attributes:
        score: detector confidence in [0, 1].
        face_box: ``(4,)`` x0, y0, x1, y1 of the face box.
        keypoints: ``(4, 2)`` mid-hip, full-body size point, mid-shoulder, upper-body size point.
    """

    score: float
    face_box: np.ndarray
    keypoints: np.ndarray


@dataclass(frozen=True)
class Roi:
    """A rotated square of the frame the landmark model looks at.

    Attributes:
        centre: ``(2,)`` pixel centre.
        size: side length in pixels.
        rotation: radians; positive turns the square clockwise on screen (image y points down).
    """

    centre: np.ndarray
    size: float
    rotation: float

    def corners(self) -> np.ndarray:
        """``(4, 2)`` pixel corners: top-left, top-right, bottom-right, bottom-left of the model's view."""
        offsets = np.array([[-0.5, -0.5], [0.5, -0.5], [0.5, 0.5], [-0.5, 0.5]]) * self.size
        return self.centre + offsets @ _rotation(self.rotation).T

    def mask(self, shape: tuple[int, int]) -> np.ndarray:
        """``(H, W)`` bool: the pixels of an ``(H, W)`` frame inside the square."""
        region = np.zeros(shape, np.uint8)
        cv2.fillConvexPoly(region, np.round(self.corners()).astype(np.int32), 1)
        return region > 0


@dataclass(frozen=True)
class Landmarks:
    """The landmark model's answer for one region.

    Attributes:
        presence: pose flag in [0, 1]; MediaPipe keeps the pose when it is ≥ 0.5.
        image: ``(39, 5)`` pixel u, v, z (pixels, same scale as u; smaller is nearer), visibility, presence.
        world: ``(33, 3)`` metres, origin between the hips, camera-aligned axes (+x right, +y down, +z away).
        segmentation: ``(H, W)`` float32 person probability on the frame (0 outside the region).
        roi: the region it looked at.
    """

    presence: float
    image: np.ndarray
    world: np.ndarray
    segmentation: np.ndarray
    roi: Roi


def _rotation(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s], [s, c]])


def _sigmoid(x: np.ndarray) -> np.ndarray:
    return 1.0 / (1.0 + np.exp(-np.clip(np.asarray(x, np.float64), -100.0, 100.0)))


def ssd_anchors() -> np.ndarray:
    """``(2254, 2)`` normalised anchor centres of the detector (``SsdAnchorsCalculator`` with the options of
    pose_detection_cpu.pbtxt: layers that share a stride share a grid, two anchors per layer per cell since
    ``interpolated_scale_aspect_ratio`` adds one to the single aspect ratio; fixed size, so only centres)."""
    strides = (8, 16, 32, 32, 32)
    centres = []
    layer = 0
    while layer < len(strides):
        stride, per_cell = strides[layer], 0
        while layer < len(strides) and strides[layer] == stride:
            per_cell += 2
            layer += 1
        cells = int(np.ceil(DETECTOR_SIZE / stride))
        grid = (np.arange(cells) + 0.5) / cells
        yy, xx = np.meshgrid(grid, grid, indexing="ij")
        centres.append(np.repeat(np.stack([xx.ravel(), yy.ravel()], axis=1), per_cell, axis=0))
    return np.concatenate(centres)


_ANCHORS = ssd_anchors()


def letterbox(image: np.ndarray) -> tuple[np.ndarray, float, np.ndarray]:
    """The detector's input: the frame fitted into 224x224 (aspect kept, zero border) in [-1, 1].

    Returns:
        ``(1, 224, 224, 3)`` float32 tensor, the scale (model pixels per frame pixel) and the ``(2,)``
        offset so that ``model = frame * scale + offset``.
    """
    h, w = image.shape[:2]
    scale = DETECTOR_SIZE / max(h, w)
    offset = np.array([(DETECTOR_SIZE - w * scale) / 2, (DETECTOR_SIZE - h * scale) / 2])
    matrix = np.array([[scale, 0, offset[0]], [0, scale, offset[1]]])
    # The sampling maps pixel centres (OpenCV's convention), as MediaPipe's warp does.
    tensor = cv2.warpAffine(image, matrix, (DETECTOR_SIZE, DETECTOR_SIZE), flags=cv2.INTER_LINEAR,
                            borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    return (tensor.astype(np.float32) / 127.5 - 1.0)[None], scale, offset


def decode_detections(raw_boxes: np.ndarray, raw_scores: np.ndarray, scale: float, offset: np.ndarray,
                      min_score: float = MIN_DETECTION_SCORE) -> list[Detection]:
    """Detections in frame pixels from the detector's ``(2254, 12)`` boxes and ``(2254,)`` logits, best
    first, after weighted non-maximum suppression (MediaPipe's ``WEIGHTED`` algorithm: each kept detection
    is the score-weighted mean of the detections overlapping it by more than the threshold)."""
    scores = _sigmoid(raw_scores.astype(np.float64))
    keep = np.flatnonzero(scores >= min_score)
    if keep.size == 0:
        return []
    values = raw_boxes[keep].astype(np.float64) / DETECTOR_SIZE
    centre = values[:, 0:2] + _ANCHORS[keep]
    half = values[:, 2:4] / 2
    boxes = np.concatenate([centre - half, centre + half], axis=1)
    keypoints = values[:, 4:12].reshape(-1, 4, 2) + _ANCHORS[keep][:, None]
    order = np.argsort(-scores[keep], kind="stable")
    remaining = list(order)
    out = []
    while remaining:
        top = remaining[0]
        overlap = _iou(boxes[top], boxes[remaining])
        cluster = [r for r, o in zip(remaining, overlap) if o > NMS_IOU]
        remaining = [r for r, o in zip(remaining, overlap) if o <= NMS_IOU]
        weights = scores[keep][cluster]
        box = (weights[:, None] * boxes[cluster]).sum(0) / weights.sum()
        points = (weights[:, None, None] * keypoints[cluster]).sum(0) / weights.sum()
        # Model coordinates (normalised to 224) back to frame pixels.
        to_frame = lambda p: (p * DETECTOR_SIZE - offset) / scale  # noqa: E731
        out.append(Detection(float(scores[keep][top]), to_frame(box.reshape(2, 2)).ravel(), to_frame(points)))
    return out


def _iou(box: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    lo = np.maximum(box[:2], boxes[:, :2])
    hi = np.minimum(box[2:], boxes[:, 2:])
    inter = np.prod(np.clip(hi - lo, 0, None), axis=1)
    area = lambda b: np.prod(np.clip(b[..., 2:] - b[..., :2], 0, None), axis=-1)  # noqa: E731
    union = area(box) + area(boxes) - inter
    return np.where(union > 0, inter / np.where(union > 0, union, 1), 0.0)


def roi_from_points(centre: np.ndarray, size_point: np.ndarray) -> Roi:
    """The square around two alignment points (``AlignmentPointsRectsCalculator`` with target angle 90°,
    then ``RectTransformationCalculator`` at scale 1.5, square): side 2 × 1.5 × their distance, rotated so
    that ``size_point`` is straight above ``centre``."""
    centre = np.asarray(centre, np.float64)
    delta = np.asarray(size_point, np.float64) - centre
    rotation = np.pi / 2 - np.arctan2(-delta[1], delta[0])
    rotation = float((rotation + np.pi) % (2 * np.pi) - np.pi)
    return Roi(centre, float(2 * np.hypot(*delta) * ROI_SCALE), rotation)


def roi_from_detection(detection: Detection) -> Roi:
    """The landmark model's first square for a detection: centred on the mid-hip, sized and turned by the
    full-body point."""
    return roi_from_points(detection.keypoints[0], detection.keypoints[1])


def roi_from_landmarks(landmarks: Landmarks) -> Roi:
    """The next frame's square from this frame's auxiliary landmarks 33 (centre) and 34 (size and tilt)."""
    return roi_from_points(landmarks.image[33, :2], landmarks.image[34, :2])


def _crop_matrix(roi: Roi) -> np.ndarray:
    """``(2, 3)`` affine from the frame to the model's 256x256 view of ``roi`` (corners onto corners)."""
    source = roi.corners()[[0, 1, 3]].astype(np.float32)
    target = np.array([[0, 0], [LANDMARK_SIZE, 0], [0, LANDMARK_SIZE]], np.float32)
    return cv2.getAffineTransform(source, target)


def crop(image: np.ndarray, roi: Roi) -> np.ndarray:
    """``(1, 256, 256, 3)`` float32 in [0, 1]: the landmark model's input (edge pixels replicated)."""
    view = cv2.warpAffine(image, _crop_matrix(roi), (LANDMARK_SIZE, LANDMARK_SIZE), flags=cv2.INTER_LINEAR,
                          borderMode=cv2.BORDER_REPLICATE)
    return (view.astype(np.float32) / 255.0)[None]


def refine_from_heatmap(points: np.ndarray, heatmap: np.ndarray) -> np.ndarray:
    """Normalised ``(N, 2)`` landmark positions moved to the sigmoid-weighted mean of the 7x7 heatmap
    window around each (``RefineLandmarksFromHeatmapCalculator``); unchanged where the window's peak is
    below 0.5 or the point falls outside the map. ``heatmap`` is ``(64, 64, N)`` logits."""
    rows, cols = heatmap.shape[:2]
    out = points.copy()
    half = (HEATMAP_KERNEL - 1) // 2
    for i, (x, y) in enumerate(points):
        col, row = int(x * cols), int(y * rows)
        if not (0 <= col < cols and 0 <= row < rows):
            continue
        r0, r1 = max(0, row - half), min(rows, row + half + 1)
        c0, c1 = max(0, col - half), min(cols, col + half + 1)
        window = _sigmoid(heatmap[r0:r1, c0:c1, i].astype(np.float64))
        total = window.sum()
        if window.max() >= REFINE_MIN_CONFIDENCE and total > 0:
            rr, cc = np.mgrid[r0:r1, c0:c1]
            out[i] = [(cc * window).sum() / total / cols, (rr * window).sum() / total / rows]
    return out


def decode_landmarks(outputs: dict[str, np.ndarray], roi: Roi, image_size: tuple[int, int]) -> Landmarks:
    """The landmark model's named outputs (``Identity`` … ``Identity_4``) for ``roi`` in frame terms."""
    raw = outputs["Identity"].reshape(NUM_LANDMARKS, 5).astype(np.float64)
    normalised = raw[:, :2] / LANDMARK_SIZE
    normalised = refine_from_heatmap(normalised, outputs["Identity_3"][0])
    rotation = _rotation(roi.rotation)
    pixels = roi.centre + ((normalised - 0.5) * roi.size) @ rotation.T
    z = raw[:, 2] / LANDMARK_SIZE * roi.size
    image = np.column_stack([pixels, z, _sigmoid(raw[:, 3]), _sigmoid(raw[:, 4])])
    world = outputs["Identity_4"].reshape(NUM_LANDMARKS, 3)[:NUM_POSE_LANDMARKS].astype(np.float64)
    world = np.column_stack([world[:, :2] @ rotation.T, world[:, 2]])
    h, w = image_size
    logits = outputs["Identity_2"][0, :, :, 0]
    segmentation = cv2.warpAffine(_sigmoid(logits).astype(np.float32), _crop_matrix(roi), (w, h),
                                  flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP, borderMode=cv2.BORDER_CONSTANT,
                                  borderValue=0)
    presence = float(np.asarray(outputs["Identity_1"]).ravel()[0])
    return Landmarks(presence, image, world, segmentation, roi)


__all__ = ["Detection", "Roi", "Landmarks", "LANDMARK_NAMES", "ssd_anchors", "letterbox", "decode_detections",
           "roi_from_points", "roi_from_detection", "roi_from_landmarks", "crop", "refine_from_heatmap",
           "decode_landmarks"]
