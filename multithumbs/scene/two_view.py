"""The shared 3D space at a cut from the two boundary frames, with pycolmap (DESIGN §1 stage 4, CPU path).

Steps (:func:`shared_space_at_cut`):

1. SIFT (pycolmap, CPU) on both frames; mutual nearest neighbours with Lowe's ratio test (OpenCV's
   brute-force matcher: pycolmap's own matcher takes seconds per pair here). Features on people are left
   out of the pose estimate: people move between shots, the room does not.
2. Relative pose: pycolmap's LO-RANSAC essential matrix with cheirality, refined with
   ``refine_relative_pose`` on the inliers.
3. Scene points: the inlier matches triangulated (pycolmap ``triangulate_point``), kept when in front of
   both cameras with a small reprojection error; confidence from the triangulation angle and that error.
4. A dense room map per frame at every ``dense_stride``-th pixel, like a learned point map: inverse depth
   (affine in the image for a plane) interpolated linearly over a Delaunay triangulation of the
   triangulated points, not across people and not across long triangle edges.
5. People's point sets from their masks: a plane sweep between the two frames over the people's pixels
   (fronto-parallel planes, aggregated colour cost, the other frame's people masks as a constraint,
   parabolic sub-plane refinement). The two frames are one instant apart, so the people are (nearly)
   the same rigid scene in both; the depth loss and the people-based scale of the method need these points.

The space's frame is camera ``a``'s (``R[0] = I``, ``t[0] = 0``), its scale makes the baseline 1 (the
method rescales it from the people). Index 0 is the frame before the cut, 1 the frame after it.

Fallbacks (``SharedSpace.fallback``), tried in order when the room gives fewer than ``min_inliers``
inliers or a degenerate geometry (median triangulation angle below ``min_triangulation_angle_deg``):

* ``"neighbour_frames"``: features pooled over the extra frames the caller passed on each side (frames of
  the same shots whose camera did not move, so they see the room the people hid at the boundary);
* ``"with_people"``: the people's features join the pose estimate (the two frames are one instant apart);
* ``"rotation_only"``: too little parallax for an essential matrix but a homography fits: the relative
  rotation from it, no translation, no scene points;
* ``"human_only"``: nothing usable (e.g. a black, uniform or textureless frame): identity cameras and no
  scene points, so the alignment relies on the people alone.

Intrinsics of real video are often unknown: :func:`default_intrinsics` is the documented guess.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy import ndimage
from scipy.spatial import Delaunay

from multithumbs.errors import InputError
from multithumbs.geometry import intrinsics_from_fov
from multithumbs.types import SharedSpace

DEFAULT_HORIZONTAL_FOV_DEG = 60.0
"""Horizontal field of view assumed for real video with unknown intrinsics (a normal lens: about 31 mm on
full frame; film and TV shots of people are mostly between 40 and 75 degrees)."""


def default_intrinsics(width: int, height: int, horizontal_fov_deg: float = DEFAULT_HORIZONTAL_FOV_DEG) -> np.ndarray:
    """``(3, 3)`` guess of a real video's intrinsics: square pixels, centred principal point, 60° horizontal FOV."""
    if width < 1 or height < 1:
        raise InputError(f"image size: expected positive width and height, got {width}x{height}")
    if not 1.0 <= horizontal_fov_deg <= 170.0:
        raise InputError(f"horizontal_fov_deg: expected 1-170 degrees, got {horizontal_fov_deg}")
    return intrinsics_from_fov(width, height, horizontal_fov_deg)


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


# ----------------------------------------------------------------------------------------------------
# Dense maps


def _grid(image_size: tuple[int, int], stride: int) -> tuple[np.ndarray, np.ndarray]:
    h, w = image_size
    vs, us = np.mgrid[0:h:stride, 0:w:stride]
    return us.ravel(), vs.ravel()


def interpolate_room(xy: np.ndarray, depth: np.ndarray, people: np.ndarray, image_size: tuple[int, int],
                     stride: int, max_edge: float) -> tuple[np.ndarray, np.ndarray]:
    """Dense room depth at the grid pixels off people: inverse depth interpolated over a Delaunay mesh.

    Triangles are rasterised into an index image with OpenCV (scipy's ``find_simplex`` took seconds for
    a 640x360 grid here); inverse depth is affine over a planar patch, so the interpolation is exact on
    planes.

    Returns:
        grid pixels ``(M, 2)`` and their depth ``(M,)``.
    """
    h, w = image_size
    if len(xy) < 3:
        return np.zeros((0, 2)), np.zeros(0)
    try:
        tri = Delaunay(xy)
    except Exception:  # collinear or duplicate points: no triangles
        return np.zeros((0, 2)), np.zeros(0)
    corners = xy[tri.simplices]                                               # (F, 3, 2)
    edges = np.linalg.norm(corners - np.roll(corners, 1, axis=1), axis=2).max(axis=1)
    index = np.full((h, w), -1, np.int32)
    fixed = np.round(corners * 16).astype(np.int32)                           # 4 bits of sub-pixel precision
    for f in np.nonzero(edges <= max_edge)[0]:
        cv2.fillConvexPoly(index, fixed[f], int(f), lineType=cv2.LINE_8, shift=4)
    us, vs = _grid(image_size, stride)
    simplex = index[vs, us]
    ok = (simplex >= 0) & ~people[vs, us]
    pix, simplex = np.stack([us[ok], vs[ok]], 1).astype(np.float64), simplex[ok]
    # Barycentric coordinates by hand: scipy's ``Delaunay.transform`` took seconds here.
    c = corners[simplex]                                                      # (M, 3, 2)
    e1, e2, d = c[:, 0] - c[:, 2], c[:, 1] - c[:, 2], pix - c[:, 2]
    det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    det = np.where(np.abs(det) > 1e-12, det, 1e-12)
    b0 = (d[:, 0] * e2[:, 1] - d[:, 1] * e2[:, 0]) / det
    b1 = (e1[:, 0] * d[:, 1] - e1[:, 1] * d[:, 0]) / det
    # Rasterised edge pixels may lie a fraction outside their triangle: extrapolate (exact on a plane).
    bary = np.stack([b0, b1, 1 - b0 - b1], 1)
    inverse = (bary * (1.0 / depth[tri.simplices[simplex]])).sum(1)
    good = inverse > 0
    return pix[good], 1.0 / inverse[good]


def _person_labels(masks: np.ndarray | None, image_size: tuple[int, int]) -> np.ndarray:
    """``(H, W)`` int person label per pixel (-1 off people) from ``(P, H, W)`` or ``(H, W)`` masks."""
    h, w = image_size
    if masks is None:
        return np.full((h, w), -1, np.int32)
    masks = np.asarray(masks, bool)
    if masks.ndim == 2:
        labels, _ = ndimage.label(masks)
        return labels.astype(np.int32) - 1
    out = np.full((h, w), -1, np.int32)
    for p in range(masks.shape[0]):
        out[masks[p] & (out < 0)] = p
    return out


def sweep_people(ref: np.ndarray, other: np.ndarray, K_ref: np.ndarray, K_other: np.ndarray, R: np.ndarray,
                 t: np.ndarray, ref_labels: np.ndarray, other_people: np.ndarray, depth_range: tuple[float, float],
                 config: TwoViewConfig) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Depth of the people's pixels of ``ref`` by a fronto-parallel plane sweep against ``other``.

    ``x_other = R x_ref + t``. The cost of a plane at a pixel is the window-averaged colour difference
    (summed over RGB, capped) plus a penalty where the plane maps the pixel off the other frame's people.
    Only the bounding box of the reference people is swept. Returns grid pixels ``(M, 2)``, depths
    ``(M,)`` and confidences ``(M,)`` in [0, 1] (how much the best plane beats the median plane).
    """
    h, w = ref_labels.shape
    us, vs = _grid((h, w), config.dense_stride)
    on = ref_labels[vs, us] >= 0
    if not on.any():
        return np.zeros((0, 2)), np.zeros(0), np.zeros(0)
    half = config.sweep_window // 2 + 1
    x0, x1 = max(int(us[on].min()) - half, 0), min(int(us[on].max()) + half + 1, w)
    y0, y1 = max(int(vs[on].min()) - half, 0), min(int(vs[on].max()) + half + 1, h)
    crop = np.ascontiguousarray(ref[y0:y1, x0:x1])
    shift = np.array([[1.0, 0.0, x0], [0.0, 1.0, y0], [0.0, 0.0, 1.0]])
    near, far = depth_range
    inv = np.linspace(1.0 / near, 1.0 / far, config.sweep_planes)
    people_u8 = other_people.astype(np.uint8)
    K_ref_inv = np.linalg.inv(K_ref)
    cap, penalty = 150, 150.0
    costs = np.empty((config.sweep_planes, on.sum()), np.float32)
    gu, gv = us[on] - x0, vs[on] - y0
    normal = np.array([0.0, 0.0, 1.0])
    for i, d_inv in enumerate(inv):
        # Plane z = 1/d_inv in ref: x_other ~ K_o (R + t n^T d_inv) K_r^-1 x_ref.
        H = K_other @ (R + np.outer(t, normal) * d_inv) @ K_ref_inv @ shift
        size = (x1 - x0, y1 - y0)
        warped = cv2.warpPerspective(other, H, size, flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP)
        on_people = cv2.warpPerspective(people_u8, H, size, flags=cv2.INTER_NEAREST | cv2.WARP_INVERSE_MAP)
        diff = cv2.absdiff(crop, warped).astype(np.uint16).sum(axis=2, dtype=np.uint16)
        cost = np.minimum(diff, cap).astype(np.float32) + penalty * (on_people == 0)
        cost = cv2.blur(cost, (config.sweep_window, config.sweep_window))
        costs[i] = cost[gv, gu]
    best = np.argmin(costs, axis=0)
    cols = np.arange(costs.shape[1])
    c0 = costs[best, cols]
    # Parabolic refinement in inverse depth.
    lo, hi = np.clip(best - 1, 0, len(inv) - 1), np.clip(best + 1, 0, len(inv) - 1)
    cl, ch = costs[lo, cols], costs[hi, cols]
    denom = cl - 2 * c0 + ch
    offset = np.where((best > 0) & (best < len(inv) - 1) & (denom > 1e-6),
                      0.5 * (cl - ch) / np.maximum(denom, 1e-6), 0.0)
    step = inv[1] - inv[0] if len(inv) > 1 else 0.0
    inv_best = inv[best] + np.clip(offset, -0.5, 0.5) * step
    median = np.median(costs, axis=0)
    confidence = np.clip((median - c0) / np.maximum(median, 1e-6), 0, 1)
    valid = (c0 < penalty) & (inv_best > 0) & (confidence >= config.min_sweep_confidence)
    pix = np.stack([us[on], vs[on]], 1).astype(np.float64)
    return pix[valid], 1.0 / inv_best[valid], confidence[valid]


def _robust_people(pix: np.ndarray, depth: np.ndarray, conf: np.ndarray, labels: np.ndarray,
                   spread: float = 0.15) -> np.ndarray:
    """Keep a person's pixels whose depth is within ``spread`` (relative) of that person's median depth."""
    keep = np.zeros(len(depth), bool)
    who = labels[pix[:, 1].astype(int), pix[:, 0].astype(int)]
    for p in np.unique(who):
        sel = who == p
        med = np.median(depth[sel])
        keep[sel] = np.abs(depth[sel] - med) <= spread * med
    return keep


# ----------------------------------------------------------------------------------------------------
# The shared space


def _prepare(frame, name: str) -> np.ndarray:
    frame = np.asarray(frame)
    if frame.ndim != 3 or frame.shape[2] != 3 or frame.dtype != np.uint8:
        raise InputError(f"{name}: expected an (H, W, 3) uint8 RGB frame, got {frame.shape} {frame.dtype}")
    return frame


def _check_masks(masks, image_size: tuple[int, int], name: str) -> np.ndarray | None:
    if masks is None:
        return None
    masks = np.asarray(masks, bool)
    if masks.ndim not in (2, 3) or masks.shape[-2:] != tuple(image_size):
        raise InputError(f"{name}: expected (H, W) or (P, H, W) bool masks with H, W = {image_size}, "
                         f"got {masks.shape}")
    return masks


def dilate(mask: np.ndarray, pixels: int) -> np.ndarray:
    """Grow a bool mask ``(H, W)`` by ``pixels`` (OpenCV, elliptic kernel)."""
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * pixels + 1, 2 * pixels + 1))
    return cv2.dilate(mask.astype(np.uint8), kernel).astype(bool)


def _union(masks: np.ndarray | None, image_size: tuple[int, int], dilation: int) -> np.ndarray:
    if masks is None:
        return np.zeros(image_size, bool)
    union = masks if masks.ndim == 2 else masks.any(axis=0)
    if dilation > 0 and union.any():
        union = dilate(union, dilation)
    return union


def _human_only(cut_frame: int, K2: np.ndarray, image_size: tuple[int, int], reason: str,
                R1: np.ndarray | None = None) -> SharedSpace:
    R = np.stack([np.eye(3), np.eye(3) if R1 is None else R1])
    return SharedSpace(cut_frame=cut_frame, K=K2, R=R, t=np.zeros((2, 3)), points=np.zeros((0, 3)),
                       pixels=np.zeros((2, 0, 2)), observed=np.zeros((2, 0), bool), confidence=np.zeros(0),
                       image_size=image_size, source="pycolmap", fallback=reason)


@dataclass(frozen=True)
class TwoViewResult:
    """A shared space with the numbers behind it.

    Attributes:
        space: the shared space.
        num_matches: feature matches between the two boundary frames.
        num_inliers: matches consistent with the relative pose of the path that ran (0 without one).
        num_triangulated: scene points triangulated from them (observed in both frames).
    """

    space: SharedSpace
    num_matches: int
    num_inliers: int
    num_triangulated: int


def shared_space_at_cut(frame_a: np.ndarray, frame_b: np.ndarray, K: np.ndarray, masks_a=None, masks_b=None,
                        cut_frame: int = 1, config: TwoViewConfig = TwoViewConfig(),
                        neighbours_a=(), neighbours_b=(), neighbour_masks_a=(), neighbour_masks_b=()) -> SharedSpace:
    """The shared space of one cut from its two boundary frames (module docstring: steps and fallbacks).

    Arguments as :func:`estimate_two_view`, which also reports match and inlier counts.
    """
    return estimate_two_view(frame_a, frame_b, K, masks_a, masks_b, cut_frame, config, neighbours_a, neighbours_b,
                             neighbour_masks_a, neighbour_masks_b).space


def estimate_two_view(frame_a: np.ndarray, frame_b: np.ndarray, K: np.ndarray, masks_a=None, masks_b=None,
                      cut_frame: int = 1, config: TwoViewConfig = TwoViewConfig(),
                      neighbours_a=(), neighbours_b=(), neighbour_masks_a=(), neighbour_masks_b=()) -> TwoViewResult:
    """The shared space of one cut from its two boundary frames, with its match statistics.

    Args:
        frame_a: ``(H, W, 3)`` uint8 RGB, the frame before the cut (``t_b - 1``).
        frame_b: the frame after it (``t_b``).
        K: ``(3, 3)`` intrinsics of both frames, or ``(2, 3, 3)`` one per frame.
        masks_a, masks_b: people's masks ``(H, W)`` or ``(P, H, W)`` bool, or None.
        cut_frame: ``t_b``.
        neighbours_a, neighbours_b: optional extra frames of the same (static-camera) shots for the
            ``neighbour_frames`` fallback, with their masks in ``neighbour_masks_*`` (or none).
    Returns:
        the :class:`TwoViewResult`; its space has ``source="pycolmap"`` and ``fallback`` says which path ran.
    """
    frame_a, frame_b = _prepare(frame_a, "frame_a"), _prepare(frame_b, "frame_b")
    if frame_a.shape != frame_b.shape:
        raise InputError(f"frame_b: size {frame_b.shape[:2]} differs from frame_a's {frame_a.shape[:2]}")
    image_size = frame_a.shape[:2]
    K = np.asarray(K, np.float64)
    if K.shape == (3, 3):
        K = np.stack([K, K])
    if K.shape != (2, 3, 3):
        raise InputError(f"K: expected (3, 3) or (2, 3, 3) intrinsics, got {K.shape}")
    masks_a = _check_masks(masks_a, image_size, "masks_a")
    masks_b = _check_masks(masks_b, image_size, "masks_b")
    people_a = _union(masks_a, image_size, config.mask_dilation)
    people_b = _union(masks_b, image_size, config.mask_dilation)

    extractor = _sift(config)
    feats_a, feats_b = extract_features(frame_a, config, extractor), extract_features(frame_b, config, extractor)
    matches = match_features(feats_a, feats_b, config.ratio)
    xy_a, xy_b = feats_a.xy[matches[:, 0]], feats_b.xy[matches[:, 1]]
    on_people = _on_mask(xy_a, people_a) | _on_mask(xy_b, people_b)

    def attempt(sel_a: np.ndarray, sel_b: np.ndarray) -> tuple[RelativePose | None, str]:
        pose = relative_pose(sel_a, sel_b, K[0], K[1], image_size, config.ransac_max_error)
        if pose is None or pose.inliers.sum() < config.min_inliers:
            return None, "few_inliers"
        _, error, angle = triangulate(sel_a[pose.inliers], sel_b[pose.inliers], K[0], K[1], pose.R, pose.t)
        good = error <= config.max_reprojection_error
        if good.sum() < config.min_inliers or np.median(angle[good]) < config.min_triangulation_angle_deg:
            return None, "degenerate"
        return pose, ""

    room_a, room_b = xy_a[~on_people], xy_b[~on_people]
    pose, why = attempt(room_a, room_b)
    fallback = ""
    pose_a, pose_b = room_a, room_b
    if pose is None and len(neighbours_a) + len(neighbours_b) > 0:
        pool_a, pool_b = _pooled_matches(frame_a, frame_b, neighbours_a, neighbours_b, neighbour_masks_a,
                                         neighbour_masks_b, people_a, people_b, config, extractor)
        pose, _ = attempt(pool_a, pool_b)
        if pose is not None:
            fallback, pose_a, pose_b = "neighbour_frames", pool_a, pool_b
    if pose is None and on_people.any():
        pose, _ = attempt(xy_a, xy_b)
        if pose is not None:
            fallback, pose_a, pose_b = "with_people", xy_a, xy_b
    if pose is None:
        R1 = _rotation_from_homography(xy_a, xy_b, K[0], K[1], config)
        if R1 is not None and why == "degenerate":
            return TwoViewResult(_human_only(cut_frame, K, image_size, "rotation_only", R1), len(matches), 0, 0)
        return TwoViewResult(_human_only(cut_frame, K, image_size, "human_only"), len(matches), 0, 0)

    # Scene points from the inliers of the path that ran.
    ia, ib = pose_a[pose.inliers], pose_b[pose.inliers]
    points, error, angle = triangulate(ia, ib, K[0], K[1], pose.R, pose.t)
    good = error <= config.max_reprojection_error
    points, ia, ib, error, angle = points[good], ia[good], ib[good], error[good], angle[good]
    confidence = np.clip(angle / 5.0, 0, 1) * np.clip(1.0 - error / (2 * config.max_reprojection_error), 0, 1)
    confidence = np.clip(confidence, 0.05, 1.0)
    R_b, t_b = pose.R, pose.t
    # Only points really observed in the two boundary frames carry pixels in both.
    depth_a, depth_b = points[:, 2], (points @ R_b.T + t_b)[:, 2]

    all_points, all_pixels, all_observed, all_conf = [points], [np.stack([ia, ib])], [np.ones((2, len(ia)), bool)], [confidence]
    rotations = (np.eye(3), R_b)
    translations = (np.zeros(3), t_b)
    for k, (xy, depth, people, frame) in enumerate(((ia, depth_a, people_a, frame_a), (ib, depth_b, people_b, frame_b))):
        pix, dense_depth = interpolate_room(xy, depth, people, image_size, config.dense_stride, config.max_triangle_edge)
        _append(all_points, all_pixels, all_observed, all_conf, k, pix, dense_depth,
                np.full(len(pix), config.interpolated_confidence), K[k], rotations[k], translations[k])
    # People: sweep each frame against the other.
    labels_a, labels_b = _person_labels(masks_a, image_size), _person_labels(masks_b, image_size)
    near = 0.3 * float(min(np.percentile(depth_a, 2), np.percentile(depth_b, 2)))
    far = 1.2 * float(max(np.percentile(depth_a, 98), np.percentile(depth_b, 98)))
    R_ba, t_ba = R_b.T, -R_b.T @ t_b
    sweeps = ((frame_a, frame_b, K[0], K[1], R_b, t_b, labels_a, labels_b >= 0),
              (frame_b, frame_a, K[1], K[0], R_ba, t_ba, labels_b, labels_a >= 0))
    for k, (ref, other, K_r, K_o, R_ro, t_ro, labels, other_people) in enumerate(sweeps):
        if not (labels >= 0).any() or not other_people.any():
            continue
        pix, depth, conf = sweep_people(ref, other, K_r, K_o, R_ro, t_ro, labels, other_people, (near, far), config)
        if len(pix) == 0:
            continue
        keep = _robust_people(pix, depth, conf, labels)
        _append(all_points, all_pixels, all_observed, all_conf, k, pix[keep], depth[keep], conf[keep], K[k],
                rotations[k], translations[k])
    space = SharedSpace(cut_frame=cut_frame, K=K, R=np.stack(rotations), t=np.stack(translations),
                        points=np.concatenate(all_points), pixels=np.concatenate(all_pixels, axis=1),
                        observed=np.concatenate(all_observed, axis=1), confidence=np.concatenate(all_conf),
                        image_size=image_size, source="pycolmap", fallback=fallback)
    return TwoViewResult(space, len(matches), int(pose.inliers.sum()), int(good.sum()))


def _append(points, pixels, observed, conf, k: int, pix: np.ndarray, depth: np.ndarray, confidence: np.ndarray,
            K: np.ndarray, R: np.ndarray, t: np.ndarray) -> None:
    """Add points seen in frame ``k`` only (pixels and depths in that frame) to the lists, in the space's frame."""
    if len(pix) == 0:
        return
    cam = np.c_[pix, np.ones(len(pix))] @ np.linalg.inv(K).T * depth[:, None]
    points.append((cam - t) @ R)
    both = np.zeros((2, len(pix), 2))
    both[k] = pix
    obs = np.zeros((2, len(pix)), bool)
    obs[k] = True
    pixels.append(both)
    observed.append(obs)
    conf.append(np.asarray(confidence, np.float64))


def _pooled_matches(frame_a, frame_b, neighbours_a, neighbours_b, masks_na, masks_nb, people_a, people_b,
                    config: TwoViewConfig, extractor) -> tuple[np.ndarray, np.ndarray]:
    """Room matches between every frame of side a and every frame of side b (boundary frames included)."""
    side_a = [(frame_a, people_a)] + [(f, _union(_check_masks(m, people_a.shape, "neighbour mask"), people_a.shape,
                                                 config.mask_dilation)) for f, m in _with_masks(neighbours_a, masks_na)]
    side_b = [(frame_b, people_b)] + [(f, _union(_check_masks(m, people_b.shape, "neighbour mask"), people_b.shape,
                                                 config.mask_dilation)) for f, m in _with_masks(neighbours_b, masks_nb)]
    feats_a = [extract_features(_prepare(f, "neighbour frame"), config, extractor) for f, _ in side_a]
    feats_b = [extract_features(_prepare(f, "neighbour frame"), config, extractor) for f, _ in side_b]
    out_a, out_b = [], []
    for fa, (_, pa) in zip(feats_a, side_a):
        for fb, (_, pb) in zip(feats_b, side_b):
            m = match_features(fa, fb, config.ratio)
            xa, xb = fa.xy[m[:, 0]], fb.xy[m[:, 1]]
            room = ~(_on_mask(xa, pa) | _on_mask(xb, pb))
            out_a.append(xa[room])
            out_b.append(xb[room])
    return np.concatenate(out_a), np.concatenate(out_b)


def _with_masks(frames, masks):
    masks = list(masks) if masks is not None else []
    return [(f, masks[i] if i < len(masks) else None) for i, f in enumerate(frames)]


def _rotation_from_homography(xy_a: np.ndarray, xy_b: np.ndarray, K_a: np.ndarray, K_b: np.ndarray,
                              config: TwoViewConfig) -> np.ndarray | None:
    """Relative rotation of a (near) pure rotation: ``R = K_b^-1 H K_a`` projected onto SO(3), or None."""
    if len(xy_a) < config.min_inliers:
        return None
    H, inliers = cv2.findHomography(xy_a, xy_b, cv2.RANSAC, config.ransac_max_error * 2)
    if H is None or inliers.sum() < config.min_inliers:
        return None
    M = np.linalg.inv(K_b) @ H @ K_a
    U, _, Vt = np.linalg.svd(M)
    R = U @ Vt
    if np.linalg.det(R) < 0:
        R = U @ np.diag([1, 1, -1]) @ Vt
    return R
