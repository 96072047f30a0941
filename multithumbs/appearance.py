"""Appearance descriptors of people from pixels, for the re-identification term A (paper §3.4).

A person's mask pixels are split into body regions (head, torso, arms, legs) by their nearest 2D bone
between confident keypoints, and each region is described by a hue-saturation histogram (robust to the
shading changes between viewpoints) plus its mean CIE Lab chromaticity. Regions with too few pixels are
marked invalid, and dissimilarity compares only the regions valid in both descriptors — the paper's
"colour differences over valid non-occluded regions" with regions instead of UV texels.

Descriptor layout, per region: ``[valid, hist (HUE_BINS * SAT_BINS), a*, b*]``.
"""

from __future__ import annotations

import cv2
import numpy as np

REGIONS = ("head", "torso", "arms", "legs")
# SMPL joint pairs forming the bones of each region.
_BONES: tuple[tuple[int, int, int], ...] = (
    (12, 15, 0),                                         # head
    (0, 3, 1), (3, 6, 1), (6, 9, 1), (9, 12, 1), (13, 16, 1), (14, 17, 1), (1, 2, 1),  # torso
    (16, 18, 2), (18, 20, 2), (17, 19, 2), (19, 21, 2),  # arms
    (1, 4, 3), (4, 7, 3), (2, 5, 3), (5, 8, 3),          # legs
)
HUE_BINS, SAT_BINS = 12, 3
REGION_SIZE = 1 + HUE_BINS * SAT_BINS + 2
DESCRIPTOR_SIZE = len(REGIONS) * REGION_SIZE


def _point_segment_distance(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``(N, S)`` distance of points ``(N, 2)`` to segments ``a, b (S, 2)``."""
    ab = b - a
    t = ((points[:, None] - a[None]) * ab[None]).sum(-1) / np.maximum((ab * ab).sum(-1), 1e-9)[None]
    closest = a[None] + np.clip(t, 0, 1)[..., None] * ab[None]
    return np.linalg.norm(points[:, None] - closest, axis=-1)


def describe_person(rgb: np.ndarray, mask: np.ndarray, keypoints: np.ndarray, min_confidence: float = 0.3,
                    min_region_pixels: int = 25) -> np.ndarray:
    """Appearance descriptor ``(DESCRIPTOR_SIZE,)`` of one person in one frame.

    Args:
        rgb: ``(H, W, 3)`` uint8 frame.
        mask: ``(H, W)`` bool, the person's visible pixels.
        keypoints: ``(24, 3)`` SMPL-order 2D joints ``u, v, confidence``.
        min_confidence: keypoints below it do not define bones.
        min_region_pixels: a region with fewer pixels is invalid.
    Returns:
        the descriptor; all-zero (every region invalid) when nothing can be described.
    """
    out = np.zeros(DESCRIPTOR_SIZE)
    ys, xs = np.nonzero(mask)
    bones = [(a, b, r) for a, b, r in _BONES if keypoints[a, 2] >= min_confidence and keypoints[b, 2] >= min_confidence]
    if xs.size < min_region_pixels or not bones:
        return out
    pix = np.stack([xs, ys], axis=1).astype(float)
    ends = np.array([[keypoints[a, :2], keypoints[b, :2]] for a, b, _ in bones])
    region_of_bone = np.array([r for _, _, r in bones])
    region = region_of_bone[_point_segment_distance(pix, ends[:, 0], ends[:, 1]).argmin(axis=1)]
    colours = rgb[ys, xs][None].astype(np.uint8)
    hsv = cv2.cvtColor(colours, cv2.COLOR_RGB2HSV_FULL)[0].astype(float)
    lab = cv2.cvtColor(colours, cv2.COLOR_RGB2LAB)[0].astype(float)
    hue_bin = np.minimum((hsv[:, 0] / 256.0 * HUE_BINS).astype(int), HUE_BINS - 1)
    sat_bin = np.minimum((hsv[:, 1] / 256.0 * SAT_BINS).astype(int), SAT_BINS - 1)
    # Near-grey pixels have no reliable hue: they all go to the lowest saturation bin, hue 0.
    hue_bin[sat_bin == 0] = 0
    cell = hue_bin * SAT_BINS + sat_bin
    for r in range(len(REGIONS)):
        sel = region == r
        if sel.sum() < min_region_pixels:
            continue
        base = r * REGION_SIZE
        hist = np.bincount(cell[sel], minlength=HUE_BINS * SAT_BINS).astype(float)
        out[base] = 1.0
        out[base + 1: base + 1 + hist.size] = hist / hist.sum()
        out[base + 1 + hist.size:base + REGION_SIZE] = (lab[sel, 1:].mean(axis=0) - 128.0) / 128.0
    return out


def appearance_dissimilarity(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Dissimilarity in [0, 1] of descriptors ``a (..., D)`` and ``b (..., D)`` over regions valid in both.

    Per region: the Hellinger distance of the histograms, averaged with the chromaticity distance
    (clipped to 1). Returns ``(...)``; 0.5 (uninformative) where no region is valid in both.
    """
    a = a.reshape(*a.shape[:-1], len(REGIONS), REGION_SIZE)
    b = b.reshape(*b.shape[:-1], len(REGIONS), REGION_SIZE)
    both = (a[..., 0] > 0) & (b[..., 0] > 0)
    hist_a, hist_b = a[..., 1:1 + HUE_BINS * SAT_BINS], b[..., 1:1 + HUE_BINS * SAT_BINS]
    hellinger = np.sqrt(np.clip(1.0 - np.sqrt(hist_a * hist_b).sum(-1), 0.0, 1.0))
    chroma = np.minimum(np.linalg.norm(a[..., -2:] - b[..., -2:], axis=-1) * 4.0, 1.0)
    per_region = 0.5 * (hellinger + chroma)
    count = both.sum(-1)
    total = np.where(both, per_region, 0.0).sum(-1)
    return np.where(count > 0, total / np.maximum(count, 1), 0.5)


def mean_descriptor(descriptors: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Average descriptors ``(N, D)`` over valid rows ``(N,)``, region by region; ``(D,)``."""
    d = descriptors[valid].reshape(-1, len(REGIONS), REGION_SIZE)
    out = np.zeros((len(REGIONS), REGION_SIZE))
    for r in range(len(REGIONS)):
        rows = d[d[:, r, 0] > 0, r]
        if len(rows):
            out[r] = rows.mean(axis=0)
            out[r, 0] = 1.0
    return out.reshape(-1)
