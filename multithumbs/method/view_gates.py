"""Smooth gates and a smooth surface lookup for the view registration (:mod:`multithumbs.method.views`).

The registration leaves out points hidden in the other view, points whose own pixel or whose target
pixels sit on a depth edge, and points that land on or next to a hole. As hard tests inside the
least-squares residual those gates switched points in and out between the solver's steps, so its path,
and with it its result, jumped with the inputs' rounding (1e-12 in, 0.2° out on s06 cut 0). Here every
gate is a continuous weight, computed once per solve from the camera the solve starts at and then held
fixed, and the surface a point is compared with is looked up with a C2 kernel: each solve minimises one
smooth, fixed objective, whose minimum moves continuously with the inputs.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage


@dataclass(frozen=True)
class SmoothGates:
    """How the registration's gates are softened and its solves are run."""

    softness: float = 0.01
    """Width of the occlusion and edge sigmoids as a fraction of their limits (the occlusion margin, the
    edge tolerance times the depth): small, so weights away from a limit are near 0 or 1 as the hard
    gates were, and proportional, so each pass's occlusion gate is as sharp relative to its scale."""

    corner_share: float = 0.02
    """Bilinear share of an unusable pixel under a point's projection at which the point's weight has
    fallen to 0 (from 1 with no such share, smoothstep between): the hard rule "all four bilinear
    corners usable" made continuous in the projection."""

    solves_per_pass: int = 2
    """Least-squares solves per coarse-to-fine pass, the weights renewed from the last solve's camera
    before each (the hard gates were re-tested at every step; fixed weights need a second look)."""

    tolerance: float = 1e-10
    """``ftol``, ``xtol`` and ``gtol`` of each solve: tight, so where a solve stops depends on its
    objective's minimum and not on the path the solver happened to take to it."""

    max_evaluations: int = 400
    """Residual evaluations per solve at most (the Jacobian's finite differences not counted)."""


def soft_below(value: np.ndarray, limit: np.ndarray | float, width: np.ndarray | float) -> np.ndarray:
    """Smooth ``value < limit``: a logistic sigmoid, 0.5 at the limit, 0.98 at ``limit - 4 width`` and
    0.02 at ``limit + 4 width``."""
    return 0.5 * (1.0 + np.tanh(0.5 * (limit - value) / np.maximum(width, 1e-12)))   # overflow-free


def smoothstep(x: np.ndarray) -> np.ndarray:
    """0 below 0, 1 above 1, the cubic ``3x² - 2x³`` between (C1)."""
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def filled_inverse_depth(depth: np.ndarray, region: np.ndarray) -> np.ndarray:
    """Inverse depth ``(H, W)`` on ``region`` and, elsewhere, that of the nearest region pixel.

    The lookup's kernel reaches a pixel or two past the region: filled this way it takes the region's
    own values there, not a hole's zero, so the looked-up surface is smooth everywhere (points near a
    hole are weighed out by :func:`corner_support`, not by a jump in the surface). Which pixel fills which
    follows from the region alone, so the fill is as continuous in the depths as the depths are.
    """
    inverse = np.where(region, 1.0 / np.where(region, depth, 1.0), 0.0)
    if not region.any():
        return inverse
    _, (iy, ix) = ndimage.distance_transform_edt(~region, return_indices=True)
    return inverse[iy, ix]


def surface_depth(filled_inverse: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Depth of the surface at pixel positions ``uv`` ``(N, 2)``: a cubic B-spline over the filled inverse
    depth (its pixels taken as the spline's coefficients, so no ringing; a 0.6 px blur on top of the
    map's smoothing). Inverse depth, because it is linear in the pixels on a plane and the spline
    reproduces linear functions: a plane is looked up unbent. C2, unlike bilinear weights, whose kinks at
    every pixel edge stopped the solver wherever its path happened to meet one."""
    inverse = ndimage.map_coordinates(filled_inverse, [uv[:, 1], uv[:, 0]], order=3, mode="nearest",
                                      prefilter=False)
    return 1.0 / np.maximum(inverse, 1e-12)


def corner_support(quality: np.ndarray, uv: np.ndarray, corner_share: float) -> np.ndarray:
    """Weight ``(N,)`` of points projecting to ``uv`` on a map of per-pixel ``quality`` ``(H, W)`` in [0, 1]
    (usable and off a depth edge): 1 when the four pixels of the bilinear lookup are all of quality 1,
    falling smoothly to 0 as the bilinear share of poor pixels reaches ``corner_share``; 0 outside the
    image. Continuous in ``uv`` (bilinear), which is all a weight held fixed during a solve needs."""
    good = ndimage.map_coordinates(quality, [uv[:, 1], uv[:, 0]], order=1, mode="grid-constant", cval=0.0,
                                   prefilter=False)
    return smoothstep(1.0 - (1.0 - good) / corner_share)
