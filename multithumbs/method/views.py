"""Registration of a cut's two boundary frames by their static scene (camera refinement for point maps
that follow their cameras).

A point observed in one boundary frame only was unprojected from that frame's depth with that frame's
camera (VGGT's depth head, the two-view backend's dense depth, the simulation), so an error of that
camera carries the frame's points with it: every loss on the people of that frame is relative to the
same camera and cannot see it. What does see it is the disagreement of the two frames' static scenes.
:func:`register_views` corrects the second frame's camera (and with it its points) so that each frame's
background points land on the other frame's surface: trust-region least squares
(``scipy.optimize.least_squares``, robust Cauchy loss, coarse to fine) on the depth difference between a point carried
into the other camera and that camera's (smoothed, bilinear) depth map where it projects. Points hidden
there (farther than the surface by more than the robust scale: furniture, the far side of an object),
points outside the other image or on a person, and depth edges are weighed out, not cut out: every
such gate is a smooth weight (a sigmoid of the occlusion margin and of the edge measure, the bilinear
share of usable pixels under a projection), so the residuals are continuous in the camera and in the
inputs. Hard gates switched points in and out between the solver's steps, and a 1e-12 change of the
inputs then moved a cut's result by 0.2° (docs/RESULTS.md, "Determinism"). The first frame's camera
fixes the gauge. Projective association with a depth residual, as in KinectFusion's tracking, but
against the depth map itself (no normals: the maps' per-pixel noise would dominate them).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage
from scipy.optimize import least_squares

from multithumbs.geometry import axis_angle_to_matrix, camera_centre


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


def soft_below(value: np.ndarray, limit: np.ndarray | float, softness: float) -> np.ndarray:
    """Smooth version of ``value < limit``: a logistic sigmoid, 0.5 at the limit, falling from 0.98 to 0.02 over
    ``±4 softness·|limit|`` around it (a relative width: limits here scale with depth or the margin)."""
    width = np.maximum(softness * np.abs(limit), 1e-12)
    return 0.5 * (1.0 + np.tanh(0.5 * (limit - value) / width))   # the logistic function, overflow-free


def register_views(point_cam: np.ndarray, usable: np.ndarray, K: np.ndarray, R: np.ndarray, t: np.ndarray,
                   samples: int = 2000, robust_scale: float = 0.3, smoothing_px: float = 3.0,
                   min_points: int = 200, edge_tolerance: float = 0.03, fine_scale: float = 0.05,
                   observed: np.ndarray | None = None, softness: float = 0.05, reweight: int = 2
                   ) -> ViewRegistration:
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
        softness: width of the occlusion and edge gates relative to their limits (:func:`soft_below`);
            small enough that the weights are near 1 or 0 away from the limits, as the hard gates were.
        reweight: solves per pass, the occlusion weights renewed from the last solve's camera before each.
    """
    R = np.asarray(R, float)
    t = np.asarray(t, float)
    own = usable if observed is None else usable & observed
    depth = np.stack([smoothed_depth(point_cam[k, ..., 2], own[k], smoothing_px, usable[k]) for k in range(2)])
    # Where smoothing bends the surface (depth edges, corners) the comparison would be biased: such
    # pixels weigh little as samples and as targets. Which pixels may be sampled does not depend on that
    # weight (a flip at a threshold would shift every later sample).
    raw = point_cam[..., 2]
    usable = usable & (depth > 0)
    own = own & usable
    edge = soft_below(np.abs(depth - raw), edge_tolerance * np.abs(raw), softness)
    support = np.where(usable, edge, 0.0)                          # (2, H, W) target weight per pixel
    present = usable.astype(float)
    # Looked up as inverse depth, which is linear in the pixels on a plane, and a spline reproduces linear
    # functions: a plane comes out unbent (as in smoothed_depth) where the lookup's pixels are all usable.
    inverse = np.where(usable, 1.0 / np.where(usable, depth, 1.0), 0.0)
    picked, picked_weight = [], []
    for k in range(2):
        idx = np.flatnonzero(own[k])
        if len(idx) < min_points:
            return ViewRegistration(R, t, np.zeros(6), float("nan"), float("nan"), 0, False)
        idx = idx[np.linspace(0, len(idx) - 1, min(samples, len(idx))).round().astype(int)]
        picked.append(point_cam[k].reshape(-1, 3)[idx])
        picked_weight.append(support[k].reshape(-1)[idx])
    centres = camera_centre(R, t)

    def cameras(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        R1 = axis_angle_to_matrix(x[:3]) @ R[1]
        return R1, centres[1] + x[3:]

    def lookup(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per sample of both frames: the depth residual ``z - surface`` in the other camera and the
        bilinear share of usable pixels under its projection (both continuous in ``x``)."""
        R1, C1 = cameras(x)
        Rs, Cs = (R[0], R1), (centres[0], C1)
        res, shares = [], []
        for k in range(2):
            j = 1 - k
            world = picked[k] @ Rs[k] + Cs[k]                     # R_k^T y + C_k
            cam = (world - Cs[j]) @ Rs[j].T                        # into the other camera
            z = cam[:, 2]
            uv = (cam @ K[j].T)[:, :2] / np.maximum(z, 1e-6)[:, None]
            # Normalised lookup: the surface from the usable pixels only (no mixing with a hole's zero),
            # weighed to 0 smoothly towards holes and beyond the image's border. A cubic B-spline
            # kernel (the pixels taken as its coefficients: a 0.6 px blur, no overshoot), not bilinear
            # weights: their kinks at every pixel edge stopped the solver where its path happened to
            # meet one, 1e-6 rad apart for inputs 1e-12 apart.
            at = [uv[:, 1], uv[:, 0]]
            look = lambda image: ndimage.map_coordinates(image, at, order=3, mode="grid-constant", cval=0.0,
                                                         prefilter=False)
            full, total, edges = look(present[j]), look(inverse[j]), look(support[j])
            # Weight: the lookup's edge weight times a smooth step from 0 (a tenth of its pixels missing)
            # to 1 (all usable): a partial lookup averages the usable pixels' depths off the point's own.
            step = np.clip((full - 0.9) / 0.1, 0.0, 1.0)
            share = step * step * (3 - 2 * step) * edges / np.maximum(full, 1e-12)
            front = (z > 1e-6) & (total > 1e-12)
            res.append(np.where(front, z - full / np.where(front, total, 1.0), 0.0))
            shares.append(np.where(front, share, 0.0))
        return np.concatenate(res), np.concatenate(shares)

    def weights(x: np.ndarray, margin: float) -> np.ndarray:
        """The samples' weights for a solve from ``x``: their pixel's edge weight and a soft occlusion gate."""
        r, _ = lookup(x)
        return np.concatenate(picked_weight) * soft_below(r, margin, softness)

    def residuals(x: np.ndarray, weight: np.ndarray) -> np.ndarray:
        r, share = lookup(x)
        return weight * share * r          # share -> 0 smoothly where the surface has no support

    def median(x: np.ndarray) -> tuple[float, int]:
        """Median absolute residual of the points that count (weight above one half; a diagnostic only)."""
        r, share = lookup(x)
        counted = np.abs(r[weights(x, robust_scale) * share > 0.5])
        return (float(np.median(counted)) if len(counted) else float("nan")), len(counted)

    before, _ = median(np.zeros(6))
    # Coarse to fine: the first pass reaches from a misregistration of decimetres, the last settles with
    # the centimetre-level points only (the wider kernels still weigh outliers of that size near-fully).
    # The occlusion weights are fixed during a solve and renewed between solves: weights that moved with
    # the camera would let it lower the cost by hiding points, gates that switched inside a solve made
    # its path, and so its result, jump with the inputs' rounding. Tolerances near the rounding: where
    # the solver stops must not depend on its path either.
    x, passes = np.zeros(6), 0
    for scale in [s for s in (3 * robust_scale, robust_scale, fine_scale) for _ in range(reweight)]:
        fit = least_squares(residuals, x, loss="cauchy", f_scale=scale, kwargs={"weight": weights(x, scale)},
                            x_scale=np.array([0.01, 0.01, 0.01, 0.05, 0.05, 0.05]), diff_step=1e-4,
                            ftol=1e-12, xtol=1e-12, gtol=1e-12)
        if not fit.success or not np.all(np.isfinite(fit.x)):
            break
        x, passes = fit.x, passes + 1
    if passes == 0:
        return ViewRegistration(R, t, np.zeros(6), before, float("nan"), 0, False)
    after, used = median(x)
    R1, C1 = cameras(x)
    return ViewRegistration(np.stack([R[0], R1]), np.stack([t[0], -R1 @ C1]), x, before, after, used, True)
