"""Scale between meshes and a shared space's points (paper §3.1).

Per person and boundary frame: the maximum centroid-to-vertex distance of the mesh over that of the
person's point cloud (points inside the person's mask); the ratio is averaged over people and applied
to the whole space. Points far from the person's median (mask bleed onto the background) are dropped
before taking the maximum, because a single stray point would otherwise set the scale.
"""

from __future__ import annotations

import numpy as np


def max_radius(points: np.ndarray) -> float:
    """Maximum distance of points ``(N, 3)`` from their centroid."""
    return float(np.linalg.norm(points - points.mean(axis=0), axis=1).max())


def trim_outliers(points: np.ndarray, factor: float = 3.0) -> np.ndarray:
    """Drop points farther from the median than ``factor`` times the median distance to it."""
    if len(points) < 4:
        return points
    dist = np.linalg.norm(points - np.median(points, axis=0), axis=1)
    return points[dist <= factor * max(np.median(dist), 1e-9)]


def mesh_to_points_scale(mesh_vertices: list[np.ndarray], person_points: list[np.ndarray],
                         min_points: int = 20) -> float:
    """Factor that brings point clouds to the meshes' scale: mean over pairs of radius(mesh)/radius(points).

    Args:
        mesh_vertices: per (person, frame) the mesh vertices ``(V, 3)`` that are visible in the image.
        person_points: the matching person point clouds ``(N, 3)``.
        min_points: pairs with fewer points are skipped.
    Returns:
        the factor; ``nan`` when no pair has enough points.
    """
    ratios = []
    for verts, pts in zip(mesh_vertices, person_points):
        pts = trim_outliers(pts)
        if len(pts) < min_points:
            continue
        radius = max_radius(pts)
        if radius > 0:
            ratios.append(max_radius(verts) / radius)
    return float(np.mean(ratios)) if ratios else float("nan")


def depth_ratio_scale(mesh_depths: list[np.ndarray], point_depths: list[np.ndarray], min_points: int = 20) -> float:
    """Mesh-to-points factor from per-pixel depths: per person the median of mesh depth / point depth, averaged.

    The same quantity as :func:`mesh_to_points_scale` — a mesh that fits a person's mask has its size in
    the ratio of its depth — but measured pixel by pixel on the visible surface, so partial visibility
    does not bias it (exact on noise-free input, where the max-radius ratio scatters by ±15%).

    Args:
        mesh_depths: per (person, frame) camera depths of mesh vertices facing the camera inside the mask.
        point_depths: the shared space's depth at the same vertices' pixels (its own units).
    """
    ratios = []
    for zm, zp in zip(mesh_depths, point_depths):
        ok = (zp > 0) & (zm > 0)
        if ok.sum() >= min_points:
            ratios.append(float(np.median(zm[ok] / zp[ok])))
    return float(np.mean(ratios)) if ratios else float("nan")
