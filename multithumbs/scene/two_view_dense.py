"""Dense points of the two-view shared space (steps 4 and 5 of
:func:`multithumbs.scene.two_view.shared_space_at_cut`): the room's depth between the triangulated points, and
the people's depth by a plane sweep.

The room: inverse depth (affine in the image for a plane) interpolated linearly over a Delaunay triangulation
of the triangulated points, not across people and not across long triangle edges. The people: a plane sweep
between the two frames over the people's pixels (fronto-parallel planes, aggregated colour cost, the other
frame's people masks as a constraint, parabolic sub-plane refinement).
"""

from __future__ import annotations

import cv2
import numpy as np
from scipy import ndimage
from scipy.spatial import Delaunay

from multithumbs.scene.two_view_pose import TwoViewConfig


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
