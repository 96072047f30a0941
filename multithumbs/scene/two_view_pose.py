"""Features, matches, relative pose and triangulation of two frames with pycolmap (steps 1-3 of
:func:`multithumbs.scene.two_view.shared_space_at_cut`), and the settings of all its steps (:class:`TwoViewConfig`).

1. SIFT (pycolmap, CPU) on both frames; mutual nearest neighbours with Lowe's ratio test (OpenCV's
   brute-force matcher: pycolmap's own matcher takes seconds per pair here).
2. Relative pose: pycolmap's LO-RANSAC essential matrix with cheirality, refined with
   ``refine_relative_pose`` on the inliers.
3. Scene points: the inlier matches triangulated (pycolmap ``triangulate_point``), with each point's
   reprojection error and triangulation angle.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np


@dataclass(frozen=True)
class TwoViewConfig:
    """Settings of the pycolmap two-view shared space.

    Attributes:
        max_features: most SIFT features per frame.
        peak_threshold: SIFT peak threshold; below COLMAP's 0.0067 so weakly textured regions (clothes)
            keep features.
        upsample: detect SIFT on the image upsampled twice (``first_octave = -1``): more, finer features.
        ratio: Lowe's ratio test of the nearest over the second nearest descriptor distance.
        ransac_max_error: RANSAC inlier threshold (pixels).
        min_inliers: fewest inliers for the room's geometry to be trusted.
        min_triangulation_angle_deg: below this median triangulation angle the geometry is degenerate.
        max_reprojection_error: triangulated points with a larger error (pixels) are dropped.
        mask_dilation: people's masks grow by this many pixels before features are left out of the pose.
        dense_stride: the dense room map and the people's points sample every ``dense_stride``-th pixel.
        max_triangle_edge: interpolation does not cross triangles with an edge longer than this (pixels).
        sweep_planes: depth hypotheses of the people's plane sweep (uniform in inverse depth).
        sweep_window: side of the cost aggregation window (pixels).
        min_sweep_confidence: people's pixels whose sweep is less distinctive than this are dropped.
        interpolated_confidence: confidence given to interpolated room points (triangulated points get
            up to 1).
    """

    max_features: int = 8192
    peak_threshold: float = 0.002
    upsample: bool = True
    ratio: float = 0.8
    ransac_max_error: float = 1.0
    min_inliers: int = 30
    min_triangulation_angle_deg: float = 1.0
    max_reprojection_error: float = 2.0
    mask_dilation: int = 5
    dense_stride: int = 2
    max_triangle_edge: float = 60.0
    sweep_planes: int = 96
    sweep_window: int = 9
    min_sweep_confidence: float = 0.05
    interpolated_confidence: float = 0.5


# ----------------------------------------------------------------------------------------------------
# Features and matches


@dataclass(frozen=True)
class Features:
    """SIFT features of one image: ``xy (N, 2)`` pixels (our convention: centres at integers), ``desc (N, 128)``."""

    xy: np.ndarray
    desc: np.ndarray


def _gray(frame: np.ndarray) -> np.ndarray:
    frame = np.asarray(frame)
    if frame.ndim == 2:
        return np.ascontiguousarray(frame, dtype=np.uint8)
    return cv2.cvtColor(np.ascontiguousarray(frame), cv2.COLOR_RGB2GRAY)


def _sift(config: TwoViewConfig):
    import pycolmap

    pycolmap.logging.minloglevel = max(int(pycolmap.logging.minloglevel), 1)  # COLMAP's INFO lines are noise here
    options = pycolmap.FeatureExtractionOptions()
    options.sift.max_num_features = config.max_features
    options.sift.peak_threshold = config.peak_threshold
    options.sift.first_octave = -1 if config.upsample else 0
    options.num_threads = 1
    import warnings

    with warnings.catch_warnings():  # pycolmap 4.2 deprecates Sift for FeatureExtractor; both work
        warnings.simplefilter("ignore", DeprecationWarning)
        return pycolmap.Sift(options, device=pycolmap.Device.cpu)


def extract_features(frame: np.ndarray, config: TwoViewConfig = TwoViewConfig(), extractor=None) -> Features:
    """SIFT features of an RGB ``(H, W, 3)`` or gray ``(H, W)`` uint8 image."""
    extractor = extractor or _sift(config)
    keypoints, desc = extractor.extract(_gray(frame))
    # COLMAP puts pixel centres at +0.5 (conventions.py).
    return Features(keypoints[:, :2].astype(np.float64) - 0.5, np.asarray(desc, np.float32))


def match_features(a: Features, b: Features, ratio: float = 0.8) -> np.ndarray:
    """``(M, 2)`` index pairs: mutual nearest neighbours passing the ratio test."""
    if len(a.xy) < 2 or len(b.xy) < 2:
        return np.zeros((0, 2), np.int64)
    matcher = cv2.BFMatcher(cv2.NORM_L2)
    forward = matcher.knnMatch(a.desc, b.desc, k=2)
    backward = matcher.match(b.desc, a.desc)
    back = np.array([m.trainIdx for m in backward])
    pairs = [(m.queryIdx, m.trainIdx) for m, n in (p for p in forward if len(p) == 2)
             if m.distance < ratio * n.distance and back[m.trainIdx] == m.queryIdx]
    return np.array(pairs, np.int64).reshape(-1, 2)


def _colmap_camera(K: np.ndarray, image_size: tuple[int, int]):
    import pycolmap

    h, w = image_size
    return pycolmap.Camera(model="PINHOLE", width=int(w), height=int(h),
                           params=[K[0, 0], K[1, 1], K[0, 2] + 0.5, K[1, 2] + 0.5])


def _on_mask(xy: np.ndarray, mask: np.ndarray | None) -> np.ndarray:
    if mask is None or len(xy) == 0:
        return np.zeros(len(xy), bool)
    h, w = mask.shape
    u = np.clip(np.round(xy[:, 0]).astype(int), 0, w - 1)
    v = np.clip(np.round(xy[:, 1]).astype(int), 0, h - 1)
    return mask[v, u]


# ----------------------------------------------------------------------------------------------------
# Relative pose and triangulation


@dataclass(frozen=True)
class RelativePose:
    """Camera b from camera a: ``x_b = R x_a + t``, ``|t| = 1``; ``inliers`` a bool mask over the matches."""

    R: np.ndarray
    t: np.ndarray
    inliers: np.ndarray


def relative_pose(xy_a: np.ndarray, xy_b: np.ndarray, K_a: np.ndarray, K_b: np.ndarray,
                  image_size: tuple[int, int], max_error: float = 1.0) -> RelativePose | None:
    """Essential-matrix LO-RANSAC and refinement with pycolmap; None when it fails."""
    import pycolmap

    if len(xy_a) < 8:
        return None
    cam_a, cam_b = _colmap_camera(K_a, image_size), _colmap_camera(K_b, image_size)
    pa, pb = np.ascontiguousarray(xy_a + 0.5), np.ascontiguousarray(xy_b + 0.5)
    # A fixed RANSAC seed: the same frames give the same space (content-addressed artifacts stay reproducible).
    result = pycolmap.estimate_essential_matrix(pa, pb, cam_a, cam_b,
                                                pycolmap.RANSACOptions(max_error=max_error, random_seed=0))
    if result is None:
        return None
    inliers = np.asarray(result["inlier_mask"], bool).reshape(-1)
    pose = result["cam2_from_cam1"]
    try:
        refined = pycolmap.refine_relative_pose(pose, cam_a, pa, cam_b, pb, inliers.reshape(-1, 1))
        pose = refined["cam2_from_cam1"] if isinstance(refined, dict) else refined
    except Exception:  # refinement is optional; keep the RANSAC pose when it cannot run
        pass
    R = np.asarray(pose.rotation.matrix(), np.float64)
    t = np.asarray(pose.translation, np.float64)
    norm = np.linalg.norm(t)
    if not norm > 0:
        return None
    return RelativePose(R, t / norm, inliers)


def triangulate(xy_a: np.ndarray, xy_b: np.ndarray, K_a: np.ndarray, K_b: np.ndarray, R: np.ndarray,
                t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points in camera a's frame from matches, with reprojection error (px) and triangulation angle (deg).

    Returns:
        points ``(N, 3)`` (nan where triangulation failed), error ``(N,)`` (max over the two views),
        angle ``(N,)``.
    """
    import pycolmap

    P_a = np.hstack([np.eye(3), np.zeros((3, 1))])
    P_b = np.hstack([R, t[:, None]])
    ia, ib = np.linalg.inv(K_a), np.linalg.inv(K_b)
    ray_a = np.c_[xy_a, np.ones(len(xy_a))] @ ia.T
    ray_b = np.c_[xy_b, np.ones(len(xy_b))] @ ib.T
    points = np.full((len(xy_a), 3), np.nan)
    for i in range(len(xy_a)):
        x = pycolmap.triangulate_point(P_a, P_b, ray_a[i, :2].reshape(2, 1), ray_b[i, :2].reshape(2, 1))
        if x is not None:
            points[i] = np.asarray(x).reshape(3)
    cam_b = points @ R.T + t
    with np.errstate(invalid="ignore", divide="ignore"):
        proj_a = points @ K_a.T
        proj_a = proj_a[:, :2] / proj_a[:, 2:]
        proj_b = cam_b @ K_b.T
        proj_b = proj_b[:, :2] / proj_b[:, 2:]
        error = np.maximum(np.linalg.norm(proj_a - xy_a, axis=1), np.linalg.norm(proj_b - xy_b, axis=1))
        centre_b = -R.T @ t
        d_a = points / np.linalg.norm(points, axis=1, keepdims=True)
        d_b = (points - centre_b) / np.linalg.norm(points - centre_b, axis=1, keepdims=True)
        angle = np.degrees(np.arccos(np.clip((d_a * d_b).sum(1), -1, 1)))
    front = (points[:, 2] > 0) & (cam_b[:, 2] > 0)
    error[~front | ~np.isfinite(error)] = np.inf
    return points, error, angle
