"""The shared 3D space at a cut from the two boundary frames, with pycolmap (DESIGN §1 stage 4, CPU path).

Steps (:func:`shared_space_at_cut`):

1. SIFT on both frames, matched (:mod:`multithumbs.scene.two_view_pose`). Features on people are left out of
   the pose estimate: people move between shots, the room does not.
2. Relative pose: an essential matrix with cheirality, refined on the inliers (``two_view_pose``).
3. Scene points: the inlier matches triangulated, kept when in front of both cameras with a small
   reprojection error; confidence from the triangulation angle and that error.
4. A dense room map per frame at every ``dense_stride``-th pixel, like a learned point map: depth
   interpolated between the triangulated points (:mod:`multithumbs.scene.two_view_dense`).
5. People's point sets from their masks: a plane sweep between the two frames over the people's pixels
   (``two_view_dense``). The two frames are one instant apart, so the people are (nearly) the same rigid
   scene in both; the depth loss and the people-based scale of the method need these points.

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

Intrinsics of real video are often unknown: :func:`default_intrinsics` is the documented guess. The settings
of every step are :class:`~multithumbs.scene.two_view_pose.TwoViewConfig`.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from multithumbs.errors import InputError
from multithumbs.geometry import intrinsics_from_fov
from multithumbs.scene.two_view_dense import _person_labels, _robust_people, interpolate_room, sweep_people
from multithumbs.scene.two_view_pose import (RelativePose, TwoViewConfig, _on_mask, _sift, extract_features,
                                             match_features, relative_pose, triangulate)
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
