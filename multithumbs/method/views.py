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
there (farther than the surface by more than the robust scale: furniture, the far side of an object)
and points outside the other image or on a person are left out. The first frame's camera fixes the
gauge. Projective association with a depth residual, as in KinectFusion's tracking, but against the
depth map itself (no normals: the maps' per-pixel noise would dominate them).
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


def register_views(point_cam: np.ndarray, usable: np.ndarray, K: np.ndarray, R: np.ndarray, t: np.ndarray,
                   samples: int = 2000, robust_scale: float = 0.3, smoothing_px: float = 3.0,
                   min_points: int = 200, edge_tolerance: float = 0.03, fine_scale: float = 0.05,
                   observed: np.ndarray | None = None) -> ViewRegistration:
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
            are left out (depth edges and corners, where the smoothed surface is not the scene's).
    """
    R = np.asarray(R, float)
    t = np.asarray(t, float)
    h, w = usable.shape[1:]
    own = usable if observed is None else usable & observed
    depth = [smoothed_depth(point_cam[k, ..., 2], own[k], smoothing_px, usable[k]) for k in range(2)]
    # Where smoothing bends the surface (depth edges, corners) the comparison would be biased: such
    # pixels neither give samples nor take them.
    raw = point_cam[..., 2]
    usable = usable & (np.stack(depth) > 0) & (np.abs(np.stack(depth) - raw) < edge_tolerance * np.abs(raw))
    own = own & usable
    picked = []
    for k in range(2):
        idx = np.flatnonzero(own[k])
        if len(idx) < min_points:
            return ViewRegistration(R, t, np.zeros(6), float("nan"), float("nan"), 0, False)
        picked.append(point_cam[k].reshape(-1, 3)[idx[np.linspace(0, len(idx) - 1, min(samples, len(idx)))
                                                     .round().astype(int)]])
    centres = camera_centre(R, t)

    def cameras(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        R1 = axis_angle_to_matrix(x[:3]) @ R[1]
        return R1, centres[1] + x[3:]

    def residuals(x: np.ndarray, keep_all: bool = False, margin: float = robust_scale) -> np.ndarray:
        R1, C1 = cameras(x)
        Rs, Cs = (R[0], R1), (centres[0], C1)
        out = []
        for k in range(2):
            j = 1 - k
            world = picked[k] @ Rs[k] + Cs[k]                     # R_k^T y + C_k
            cam = (world - Cs[j]) @ Rs[j].T                        # into the other camera
            z = cam[:, 2]
            uv = (cam @ K[j].T)[:, :2] / np.maximum(z, 1e-6)[:, None]
            surface = ndimage.map_coordinates(depth[j], [uv[:, 1], uv[:, 0]], order=1, mode="nearest")
            # All four pixels of the bilinear lookup must be usable (no mixing with a hole's zero).
            corner = np.floor(uv).astype(int)
            inside = (z > 1e-6) & (corner[:, 0] >= 0) & (corner[:, 0] < w - 1) & (corner[:, 1] >= 0) & \
                (corner[:, 1] < h - 1)
            ok = inside.copy()
            cu, cv = corner[inside, 0], corner[inside, 1]
            ok[inside] = usable[j][cv, cu] & usable[j][cv, cu + 1] & usable[j][cv + 1, cu] & usable[j][cv + 1, cu + 1]
            r = z - surface
            ok &= r < margin                                       # farther than the surface: hidden there
            out.append(np.where(ok, r, 0.0) if not keep_all else np.where(ok, r, np.nan))
        return np.concatenate(out)

    median = lambda r: float(np.median(np.abs(r[np.isfinite(r)]))) if np.isfinite(r).any() else float("nan")
    before = residuals(np.zeros(6), keep_all=True)
    # Coarse to fine: the first pass reaches from a misregistration of decimetres, the last settles with
    # the centimetre-level points only (the wider kernels still weigh outliers of that size near-fully).
    x, passes = np.zeros(6), 0
    for scale in (3 * robust_scale, robust_scale, fine_scale):
        fit = least_squares(residuals, x, loss="cauchy", f_scale=scale, kwargs={"margin": scale},
                            x_scale=np.array([0.01, 0.01, 0.01, 0.05, 0.05, 0.05]), diff_step=1e-4)
        if not fit.success or not np.all(np.isfinite(fit.x)):
            break
        x, passes = fit.x, passes + 1
    if passes == 0:
        return ViewRegistration(R, t, np.zeros(6), median(before), float("nan"), 0, False)
    after = residuals(x, keep_all=True)
    R1, C1 = cameras(x)
    return ViewRegistration(np.stack([R[0], R1]), np.stack([t[0], -R1 @ C1]), x, median(before), median(after),
                            int(np.isfinite(after).sum()), True)
