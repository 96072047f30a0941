"""Registration of a cut's two boundary frames by their static scene (camera refinement for point maps
that follow their cameras).

A point observed in one boundary frame only was unprojected from that frame's depth with that frame's
camera (VGGT's depth head, the two-view backend's dense depth, the simulation), so an error of that
camera carries the frame's points with it: every loss on the people of that frame is relative to the
same camera and cannot see it. What does see it is the disagreement of the two frames' static scenes.
:func:`register_views` corrects the second frame's camera (and with it its points) so that each frame's
background points land on the other frame's surface: trust-region least squares
(``scipy.optimize.least_squares``, robust Cauchy loss, coarse to fine) on the depth difference between a point carried
into the other camera and that camera's (smoothed, cubic B-spline) depth map where it projects. Points hidden
there (farther than the surface by more than the robust scale: furniture, the far side of an object),
points outside the other image or on a person, and depth edges are weighed out by smooth gates held
fixed during each solve (:mod:`multithumbs.method.view_gates`: hard gates re-tested at every step
moved a cut's result by 0.2° for a 1e-12 change of the inputs). The first frame's camera fixes the
gauge. Projective association with a depth residual, as in KinectFusion's tracking, but against the
depth map itself (no normals: the maps' per-pixel noise would dominate them).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage
from scipy.optimize import least_squares

from multithumbs.geometry import axis_angle_to_matrix, camera_centre
from multithumbs.method.view_gates import (SmoothGates, corner_support, filled_inverse_depth, soft_below,
                                            surface_depth)


@dataclass(frozen=True)
class ViewRegistration:
    """Outcome of :func:`register_views`.

    Attributes:
        R: ``(2, 3, 3)`` world-to-camera rotations (frame 0 unchanged).
        t: ``(2, 3)`` translations.
        correction: ``(6,)`` axis-angle and centre shift applied to frame 1's camera.
        residual_before, residual_after: median absolute depth residual (m) of the points used.
        points_used: points that took part at the end.
        registered: False when there were too few points to register (cameras returned unchanged).
    """

    R: np.ndarray
    t: np.ndarray
    correction: np.ndarray
    residual_before: float
    residual_after: float
    points_used: int
    registered: bool


def smoothed_depth(depth: np.ndarray, valid: np.ndarray, sigma_px: float,
                   region: np.ndarray | None = None) -> np.ndarray:
    """Depth ``(H, W)`` smoothed from the valid pixels only (normalised Gaussian convolution), given on
    ``region`` (default: the valid pixels; it may include holes between them) and 0 elsewhere.

    Inverse depth is what is smoothed: on a plane it is linear in the pixel coordinates, so a plane comes
    out unchanged (depth itself is not, and would be bent where a floor recedes).
    """
    ok = valid & (depth > 0)
    region = ok if region is None else region
    inverse = np.where(ok, 1.0 / np.where(ok, depth, 1.0), 0.0)
    weight = ndimage.gaussian_filter(ok.astype(float), sigma_px)
    smooth = ndimage.gaussian_filter(inverse, sigma_px) / np.maximum(weight, 1e-9)
    return np.where(region & (weight > 1e-3) & (smooth > 0), 1.0 / np.maximum(smooth, 1e-12), 0.0)


def register_views(point_cam: np.ndarray, usable: np.ndarray, K: np.ndarray, R: np.ndarray, t: np.ndarray,
                   samples: int = 2000, robust_scale: float = 0.3, smoothing_px: float = 3.0,
                   min_points: int = 200, edge_tolerance: float = 0.03, fine_scale: float = 0.05,
                   observed: np.ndarray | None = None, gates: SmoothGates = SmoothGates()) -> ViewRegistration:
    """Correct frame 1's camera so both frames' static scenes agree (module docstring).

    Args:
        point_cam: ``(2, H, W, 3)`` each frame's scene points in its own camera frame (metric).
        usable: ``(2, H, W)`` bool, static background pixels whose points follow their camera.
        observed: ``(2, H, W)`` bool, pixels holding a point of their own (not a filled hole's copy of a
            neighbour, which sits half a pixel off and would bias the registration); default: all.
        K, R, t: ``(2, 3, 3)``, ``(2, 3, 3)``, ``(2, 3)`` the frames' cameras in the (metric) space.
        samples: points sampled per frame (an even subsample of the usable pixels).
        robust_scale: Cauchy scale and occlusion margin (m) of the middle pass; the first pass uses three
            times it.
        fine_scale: the same for the last pass.
        smoothing_px: Gaussian smoothing of the depth maps the points are compared with (pixels).
        min_points: fewest usable points per frame to attempt a registration.
        edge_tolerance: pixels whose smoothed depth differs from their own by more than this fraction
            are weighed out (depth edges and corners, where the smoothed surface is not the scene's).
        gates: how the gates are softened and the solves run (:class:`SmoothGates`).
    """
    R = np.asarray(R, float)
    t = np.asarray(t, float)
    own = usable if observed is None else usable & observed
    depth = np.stack([smoothed_depth(point_cam[k, ..., 2], own[k], smoothing_px, usable[k]) for k in range(2)])
    # Which pixels exist follows from the masks alone; the edge test is a weight (a pixel switched out
    # of the sample set at a threshold would shift every later sample).
    usable = usable & (depth > 0)
    own = own & usable
    raw = np.abs(point_cam[..., 2])
    # Where smoothing bends the surface (depth edges, corners) the comparison would be biased: such
    # pixels weigh little as samples and as targets.
    limit = edge_tolerance * raw
    quality = np.where(usable, soft_below(np.abs(depth - point_cam[..., 2]), limit, gates.softness * limit), 0.0)
    inverse = [filled_inverse_depth(depth[k], usable[k]) for k in range(2)]
    picked, picked_weight = [], []
    for k in range(2):
        idx = np.flatnonzero(own[k])
        if len(idx) < min_points:
            return ViewRegistration(R, t, np.zeros(6), float("nan"), float("nan"), 0, False)
        idx = idx[np.linspace(0, len(idx) - 1, min(samples, len(idx))).round().astype(int)]
        picked.append(point_cam[k].reshape(-1, 3)[idx])
        picked_weight.append(quality[k].reshape(-1)[idx])
    own_weight = np.concatenate(picked_weight)
    centres = camera_centre(R, t)

    def cameras(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        R1 = axis_angle_to_matrix(x[:3]) @ R[1]
        return R1, centres[1] + x[3:]

    def project(x: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
        """Per frame k: its samples' depth ``z`` and pixel ``uv`` in the other camera."""
        R1, C1 = cameras(x)
        Rs, Cs = (R[0], R1), (centres[0], C1)
        out = []
        for k in range(2):
            j = 1 - k
            world = picked[k] @ Rs[k] + Cs[k]                     # R_k^T y + C_k
            cam = (world - Cs[j]) @ Rs[j].T                        # into the other camera
            z = cam[:, 2]
            out.append((z, (cam @ K[j].T)[:, :2] / np.maximum(z, 1e-6)[:, None]))
        return out

    def residuals(x: np.ndarray, weight: np.ndarray) -> np.ndarray:
        return weight * np.concatenate([z - surface_depth(inverse[1 - k], uv) for k, (z, uv) in enumerate(project(x))])

    def weights(x: np.ndarray, margin: float) -> np.ndarray:
        """The samples' weights for a solve starting at ``x``: their own pixel's edge weight, the support
        where they land, and the occlusion gate (farther than the surface: hidden there)."""
        r = residuals(x, np.ones_like(own_weight))
        support = np.concatenate([corner_support(quality[1 - k], uv, gates.corner_share) * (z > 1e-6)
                                  for k, (z, uv) in enumerate(project(x))])
        return own_weight * support * soft_below(r, margin, gates.softness * margin)

    def median(x: np.ndarray) -> tuple[float, int]:
        """Median absolute residual of the points that count (weight above one half; a diagnostic)."""
        r = np.abs(residuals(x, np.ones_like(own_weight))[weights(x, robust_scale) > 0.5])
        return (float(np.median(r)) if len(r) else float("nan")), len(r)

    before, _ = median(np.zeros(6))
    # Coarse to fine: the first pass reaches from a misregistration of decimetres, the last settles with
    # the centimetre-level points only (the wider kernels still weigh outliers of that size near-fully).
    # The weights are held fixed during a solve and renewed between solves: weights that moved with the
    # camera would let it lower the cost by hiding points; gates re-tested at every step made the
    # solver's path, and so its result, jump with the inputs' rounding.
    x, passes = np.zeros(6), 0
    for scale in (3 * robust_scale, robust_scale, fine_scale):
        for _ in range(gates.solves_per_pass):
            fit = least_squares(residuals, x, loss="cauchy", f_scale=scale, kwargs={"weight": weights(x, scale)},
                                x_scale=np.array([0.01, 0.01, 0.01, 0.05, 0.05, 0.05]), diff_step=1e-4,
                                ftol=gates.tolerance, xtol=gates.tolerance, gtol=gates.tolerance,
                                max_nfev=gates.max_evaluations)
            if fit.status < 0 or not np.all(np.isfinite(fit.x)):
                break
            x = fit.x
        else:
            passes += 1
            continue
        break
    if passes == 0:
        return ViewRegistration(R, t, np.zeros(6), before, float("nan"), 0, False)
    after, used = median(x)
    R1, C1 = cameras(x)
    return ViewRegistration(np.stack([R[0], R1]), np.stack([t[0], -R1 @ C1]), x, before, after, used, True)
