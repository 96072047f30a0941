"""Which way a head faces, from its colours: a face shows skin below the hair, the back of a head only hair.

BlazePose takes a back for a front when nothing in the picture says otherwise (:mod:`.facing`), and the
walk, which decides most of those frames, says nothing where a person stands. The head does. Seen from
behind, its middle has the colour of its crown (hair, which shows from both sides); seen from the front,
its middle is a face, unlike the crown wherever the person's hair is unlike their skin. So in each frame
the head's middle is compared with its crown (:func:`face_evidence`): +1 where they differ (a face), -1
where they are alike (the back of a head), and 0 where the cue cannot tell: heads too small to sample, and
every frame of a person whose hair looks like their skin (the crown's colour over the track against the
hands': shaven heads, fair hair on fair skin, hats).

Colours are compared as chromaticity and log brightness (:func:`colour_features`), so that the shading
across one head (its lit and unlit sides differ about twofold in the suite's renders) counts for little,
and black hair, whose chromaticity is a skin's, still stands apart by brightness. Points are placed from
the landmarks whichever way BlazePose read the body, so the cue does not inherit its confusion: the head's
middle just under the mid-point of the ears, the crown above it along the neck (mid-shoulders to mid-ears),
the hands at the mean of each wrist, pinky and index finger; each is the median of the person's own mask
pixels in a small disc there.

A head turned obliquely away still shows a cheek between the ears, so the cue leans to "face" on backs
seen more from the side than from behind; the walk decides those frames where the person moves.

The labelling uses the cue on whole bodies only (hips, knees and ankles seen), as it does the walk
(:func:`multithumbs.perception.blazepose_backend.poses_to_tracks`). The crown is placed by the neck's
length, which suits a whole adult body; on Megamind.avi's close-ups (large cartoon heads, hairlines well
above the suite's) it fell on foreheads, faces read as backs, and in every frame whose hips were seen the
cue relabelled 29 of 422 person-frames; on whole bodies only, none.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

EARS = (7, 8)
SHOULDERS = (11, 12)
HANDS = ((15, 17, 19), (16, 18, 20))


@dataclass(frozen=True)
class HeadColourConfig:
    """How a head's colours are read (module docstring)."""

    enabled: bool = True
    """Read the cue; when False :func:`face_evidence` is 0 everywhere."""
    min_neck_px: float = 6.0
    """Pixels from the mid-shoulders to the mid-ears below which a head is too small to sample."""
    middle_offset: float = 0.1
    """Where the head's middle is sampled: this fraction of the neck (mid-shoulders to mid-ears) below the
    ears, clear of a front hairline."""
    crown_offset: float = 0.35
    """Where the crown is sampled: this fraction of the neck above the ears (the hair of a face seen from the
    front starts a few centimetres above the ears; the top of the head is ~0.6 neck above them)."""
    patch_radius: float = 0.1
    """Radius of each sampled disc, as a fraction of the neck (at least one pixel)."""
    min_visibility: float = 0.5
    """BlazePose visibility each ear, or each landmark of a hand, needs to be sampled."""
    chroma_scale: float = 0.03
    """Chromaticity difference (r/(r+g+b), g/(r+g+b)) that counts as one unit of colour distance."""
    brightness_scale: float = 0.5
    """Natural-log brightness ratio that counts as one unit of colour distance."""
    min_samples: int = 3
    """Frames of a track whose hands and crown must be sampled for its hair-against-skin contrast."""
    min_hair_contrast: float = 0.8
    """Colour distance between a track's crown and hands (medians) below which its hair cannot be told from
    its skin and the cue says nothing for it (the suite's shaven heads: 0.0-0.3; hair: 1.0-4.9)."""
    face_distance: float = 1.0
    """Colour distance between the head's middle and its crown at which the cue is undecided: the suite's
    backs had medians of 0.0-0.8 per track, its faces 1.4-1.9."""
    distance_spread: float = 0.5
    """Colour distance either side of ``face_distance`` over which the cue goes from -1 to +1."""


def colour_features(rgb: np.ndarray) -> np.ndarray:
    """``(..., 3)`` chromaticity r, g and natural-log brightness of ``rgb (..., 3)`` 0-255 colours."""
    rgb = np.asarray(rgb, dtype=np.float64)
    total = rgb.sum(-1, keepdims=True) + 1.0
    return np.concatenate([rgb[..., :2] / total, np.log(total)], axis=-1)


def colour_distance(a: np.ndarray, b: np.ndarray, config: HeadColourConfig = HeadColourConfig()) -> np.ndarray:
    """``(...)`` distance between features ``a, b (..., 3)`` (:func:`colour_features`), in the config's units."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    chroma = ((a[..., :2] - b[..., :2]) ** 2).sum(-1) / config.chroma_scale ** 2
    return np.sqrt(chroma + ((a[..., 2] - b[..., 2]) / config.brightness_scale) ** 2)


def _disc_median(frame: np.ndarray, mask: np.ndarray, centre: np.ndarray, radius: float) -> np.ndarray | None:
    """Median colour ``(3,)`` of the ``mask`` pixels of ``frame`` within ``radius`` of ``centre`` (u, v)."""
    h, w = mask.shape
    r = int(np.ceil(radius))
    u, v = int(round(centre[0])), int(round(centre[1]))
    x0, x1, y0, y1 = max(u - r, 0), min(u + r + 1, w), max(v - r, 0), min(v + r + 1, h)
    if x0 >= x1 or y0 >= y1:
        return None
    ys, xs = np.mgrid[y0:y1, x0:x1]
    inside = ((xs - centre[0]) ** 2 + (ys - centre[1]) ** 2 <= radius ** 2) & mask[y0:y1, x0:x1]
    if not inside.any():
        return None
    return np.median(frame[y0:y1, x0:x1][inside].astype(np.float64), axis=0)


def head_samples(frames: Sequence[np.ndarray], image: np.ndarray, masks: np.ndarray, valid: np.ndarray,
                 config: HeadColourConfig = HeadColourConfig()) -> np.ndarray:
    """Colour features ``(P, T, 3, 3)`` (:func:`colour_features`) of each person's head middle, crown and
    hands, in that order (module docstring).

    Args:
        frames: the shot's ``T`` RGB uint8 frames ``(H, W, 3)``.
        image: ``(P, T, 33, 5)`` BlazePose's landmarks (pixel u, v, z, visibility, presence).
        masks: ``(P, T, H, ceil(W/8))`` bit-packed person masks.
        valid: ``(P, T)`` bool.
    Returns:
        nan where a point was not sampled (invalid frame, small or unseen head, hands not seen, no mask
        pixel there).
    """
    image, valid = np.asarray(image, dtype=np.float64), np.asarray(valid, bool)
    out = np.full(valid.shape + (3, 3), np.nan)
    if not config.enabled:
        return out
    for t in np.flatnonzero(valid.any(0)):
        frame = np.asarray(frames[t])
        for p in np.flatnonzero(valid[:, t]):
            points = image[p, t]
            if points[list(EARS), 3].min() < config.min_visibility:
                continue
            ears, shoulders = points[list(EARS), :2].mean(0), points[list(SHOULDERS), :2].mean(0)
            neck = ears - shoulders
            length = float(np.linalg.norm(neck))
            if length < config.min_neck_px:
                continue
            mask = np.unpackbits(masks[p, t], axis=-1, count=frame.shape[1]).astype(bool)
            radius = max(1.0, config.patch_radius * length)
            centres = [ears - config.middle_offset * neck, ears + config.crown_offset * neck]
            for i, centre in enumerate(centres):
                sample = _disc_median(frame, mask, centre, radius)
                if sample is not None:
                    out[p, t, i] = colour_features(sample)
            hands = [_disc_median(frame, mask, points[list(h), :2].mean(0), radius) for h in HANDS
                     if points[list(h), 3].min() >= config.min_visibility]
            hands = [s for s in hands if s is not None]
            if hands:
                out[p, t, 2] = colour_features(np.mean(hands, axis=0))
    return out


def face_evidence(samples: np.ndarray, config: HeadColourConfig = HeadColourConfig()) -> np.ndarray:
    """``(P, T)`` in [-1, 1]: +1 where the head's middle is unlike its crown (a face), -1 where alike (the
    back of a head), 0 where the cue cannot tell (module docstring). ``samples (P, T, 3, 3)`` from
    :func:`head_samples`."""
    samples = np.asarray(samples, dtype=np.float64)
    evidence = np.zeros(samples.shape[:2])
    if not config.enabled:
        return evidence
    seen = np.isfinite(samples).all(-1)  # (P, T, 3)
    for p in range(samples.shape[0]):
        if min(seen[p, :, 1].sum(), seen[p, :, 2].sum()) < config.min_samples:
            continue
        crown, hand = np.median(samples[p, seen[p, :, 1], 1], axis=0), np.median(samples[p, seen[p, :, 2], 2], axis=0)
        if colour_distance(crown, hand, config) < config.min_hair_contrast:
            continue
        both = seen[p, :, 0] & seen[p, :, 1]
        distance = colour_distance(samples[p, both, 0], samples[p, both, 1], config)
        evidence[p, both] = np.clip((distance - config.face_distance) / config.distance_spread, -1.0, 1.0)
    return evidence


__all__ = ["HeadColourConfig", "colour_features", "colour_distance", "head_samples", "face_evidence"]
