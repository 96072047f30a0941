"""What each tracked person looks like, for the tracker's identity decisions (:mod:`.pose_tracking`).

Box overlap cannot tell who is who where two people cross: the rear person's square slides onto the
front one, and a track that is found again takes whichever lost track's last box it overlaps. So each
track keeps a model of its appearance — :mod:`multithumbs.appearance`'s descriptor (region hue-saturation
histograms and chromaticity, regions split by the skeleton) of its reading's segmentation, averaged
region by region over the frames it overlaps nobody — and the tracker asks it three questions:

* does this frame's reading still look like the person (a reading far from the model has slid onto
  someone else, and is dropped)?
* which of two tracks reading one person owns it (the other has slid)?
* which lost track is a person found again (the best box overlap, unless another lost track looks
  clearly more like them; and, for a gap too long for the box to mean anything, appearance alone)?

On the standard suite's cached tracks (session 11, ``docs/RESULTS.md``) a model's dissimilarity to later
readings of its own person is 0.12 at the median and 0.40 at the 95th percentile; to other people's it is
0.85 at the median and 0.63 at the 10th percentile, except for people dressed alike (0.04–0.06), where the
margins below leave the decision to the boxes. Descriptors are taken at half resolution (a quarter of the
pixels; ~3 ms per person against ~12 ms at full size).
"""

from __future__ import annotations

import numpy as np

from multithumbs.appearance import REGION_SIZE, REGIONS, appearance_dissimilarity, describe_person
from multithumbs.perception.appearance import complete_skeleton
from multithumbs.perception.joints import blazepose33_to_smpl24

_STEP = 2
"""Pixels between the samples a descriptor is taken on, along each axis."""


def reading_descriptor(frame: np.ndarray, segmentation: np.ndarray, landmarks_image: np.ndarray,
                       mask_probability: float = 0.5) -> np.ndarray:
    """``(D,)`` descriptor of one reading: ``frame (H, W, 3)`` RGB, ``segmentation (H, W)`` the landmark
    model's person probability on the frame, ``landmarks_image (33+, 5)`` its pixel landmarks."""
    keypoints = blazepose33_to_smpl24(np.concatenate([landmarks_image[:33, :2], landmarks_image[:33, 3:4]], -1))
    keypoints = complete_skeleton(keypoints)
    keypoints[:, :2] /= _STEP
    mask = segmentation[::_STEP, ::_STEP] >= mask_probability
    return describe_person(frame[::_STEP, ::_STEP], mask, keypoints, min_region_pixels=25 // _STEP ** 2 + 1)


def updated_model(model: np.ndarray | None, counts: np.ndarray | None, descriptor: np.ndarray,
                  memory: int) -> tuple[np.ndarray | None, np.ndarray | None]:
    """A track's model after one more reading: each region valid in ``descriptor`` moves towards it by
    ``1 / (n + 1)``, ``n`` its earlier readings capped at ``memory`` (a running mean that keeps adapting).
    ``model (D,)``, ``counts (regions,)``; None before the first reading."""
    regions = descriptor.reshape(len(REGIONS), REGION_SIZE)
    seen = regions[:, 0] > 0
    if not seen.any():
        return model, counts
    if model is None:
        return descriptor.copy(), seen.astype(np.int64)
    out = model.reshape(len(REGIONS), REGION_SIZE).copy()
    counts = counts.copy()
    step = 1.0 / (np.minimum(counts, memory) + 1.0)
    out[seen] += step[seen, None] * (regions[seen] - out[seen])
    out[seen, 0] = 1.0
    counts[seen] += 1
    return out.reshape(-1), counts


def model_dissimilarity(model: np.ndarray | None, counts: np.ndarray | None, descriptor: np.ndarray,
                        min_readings: int) -> float:
    """Dissimilarity in [0, 1] of a reading to a model learnt from at least ``min_readings`` readings in
    some region both describe; NaN when there is no such model or nothing to compare."""
    if model is None or descriptor is None:
        return float("nan")
    regions = descriptor.reshape(len(REGIONS), REGION_SIZE)
    learnt = (counts >= min_readings) & (regions[:, 0] > 0)
    if not learnt.any():
        return float("nan")
    kept = model.reshape(len(REGIONS), REGION_SIZE).copy()
    kept[~learnt, 0] = 0.0
    return float(appearance_dissimilarity(kept.reshape(-1), descriptor))


def clearly_better(dissimilarities: list[float], margin: float) -> int | None:
    """Index of the lowest dissimilarity when it beats every other finite one by ``margin`` (None when no
    value is finite or the lowest is not clear)."""
    values = np.asarray(dissimilarities, np.float64)
    finite = np.isfinite(values)
    if not finite.any():
        return None
    best = int(np.nanargmin(values))
    others = values[finite & (np.arange(values.size) != best)]
    return best if not others.size or others.min() - values[best] >= margin else None


__all__ = ["reading_descriptor", "updated_model", "model_dissimilarity", "clearly_better"]
