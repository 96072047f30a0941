"""Shared machinery of the metrics (docs/METRICS.md "Shared machinery").

Masked per-sample values, the pelvis, Umeyama similarity fits over masked points and per chunk of a
track's valid frames, the compression of valid frames (:class:`ValidFrames`, as WHAM/GVHMR), frame
windows that may not span a cut, and the pairing of every true person with one predicted identity.
Arrays are numpy float64; time series are ``(P, T, ...)`` with a boolean ``valid (P, T)``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, Sequence

import numpy as np
import torch
from scipy.optimize import linear_sum_assignment

from multithumbs.errors import InputError
from multithumbs.geometry import Similarity, umeyama

MM_PER_M = 1000.0
"""Millimetres per metre: joint errors are reported in mm."""

PELVIS_JOINTS = (1, 2)
"""SMPL joints whose mean is the pelvis used for root alignment (left and right hip, as GVHMR)."""


@dataclass(frozen=True)
class Samples:
    """Per-sample values of one metric (per frame, per triplet, per joint...) and which of them count.

    Attributes:
        values: ``(...)`` float64 value of every sample; meaningless where ``mask`` is False.
        mask: ``(...)`` bool, the sample is scored.
    """

    values: np.ndarray
    mask: np.ndarray

    def __post_init__(self) -> None:
        values = np.asarray(self.values, dtype=np.float64)
        mask = np.asarray(self.mask, dtype=bool)
        if values.shape != mask.shape:
            raise InputError(f"Samples.mask: shape {mask.shape} differs from values {values.shape}")
        object.__setattr__(self, "values", values)
        object.__setattr__(self, "mask", mask)

    @property
    def scored(self) -> np.ndarray:
        """``(N,)`` the values of the scored samples."""
        return self.values[self.mask]

    @property
    def count(self) -> int:
        return int(self.mask.sum())

    def mean(self) -> float:
        """Mean over scored samples; NaN when there is none (a metric with nothing to score)."""
        return float(self.scored.mean()) if self.count else float("nan")

    def rms(self) -> float:
        """Root mean square over scored samples; NaN when there is none."""
        return float(np.sqrt(np.mean(self.scored ** 2))) if self.count else float("nan")

    @staticmethod
    def concatenate(parts: Sequence["Samples"]) -> "Samples":
        """The scored samples of all parts as one flat set (frame-weighted pooling across sequences)."""
        values = np.concatenate([p.scored for p in parts]) if parts else np.zeros(0)
        return Samples(values, np.ones(values.shape, dtype=bool))


def pelvis(joints: np.ndarray) -> np.ndarray:
    """``(..., 24, 3)`` SMPL joints to the ``(..., 3)`` pelvis: the mean of the two hips."""
    return joints[..., PELVIS_JOINTS, :].mean(axis=-2)


def apply_similarity(sim: Similarity, points: np.ndarray) -> np.ndarray:
    """Apply ``sim`` (batch ``...``) to numpy points ``(..., N, 3)``; returns float64 numpy."""
    out = sim.apply(torch.from_numpy(np.asarray(points, dtype=np.float64)))
    return out.detach().cpu().numpy()


def fit_similarity(source: np.ndarray, target: np.ndarray, mask: np.ndarray | None = None,
                   with_scale: bool = True) -> tuple[Similarity, np.ndarray]:
    """Umeyama Sim(3) (SE(3) without scale) mapping ``source (..., N, 3)`` onto ``target`` over masked points.

    Args:
        source: ``(..., N, 3)`` points to move (the prediction).
        target: ``(..., N, 3)`` points to reach (the truth).
        mask: ``(..., N)`` bool, the points that take part; all when None.
        with_scale: Sim(3) when True, SE(3) when False.
    Returns:
        the similarity (batch ``...``) and ``fitted (...)`` bool: the batch entry had at least one point.
        Entries without points get the identity, so the result stays finite.
    """
    source = np.asarray(source, dtype=np.float64)
    target = np.asarray(target, dtype=np.float64)
    if mask is None:
        mask = np.ones(source.shape[:-1], dtype=bool)
    mask = np.broadcast_to(mask, source.shape[:-1])
    fitted = mask.any(axis=-1)
    # Unused points are zeroed (their values may be anything) and empty batches get uniform weights
    # on identical dummy points, which give the identity instead of 0/0.
    keep = mask[..., None]
    x = np.where(keep, source, 0.0)
    y = np.where(keep, target, 0.0)
    weights = np.where(fitted[..., None], mask, True).astype(np.float64)
    empty = ~fitted
    if empty.any():
        dummy = np.eye(3)[np.arange(x.shape[-2]) % 3]
        x[empty] = dummy
        y[empty] = dummy
    return umeyama(x, y, weights=weights, with_scale=with_scale), fitted


@dataclass(frozen=True)
class ValidFrames:
    """Each track's valid frames moved to the front, in order: the compression of WHAM and GVHMR.

    Those references drop invalid frames and treat the rest as consecutive, so chunks, differences and
    windows run over a track's valid frames; packing does the same on padded ``(P, T, ...)`` arrays.

    Attributes:
        order: ``(P, T)`` int, ``order[p, i]`` is the frame of track ``p`` stored at packed position ``i``
            (valid frames first, in time order, then the invalid ones).
        valid: ``(P, T)`` bool, packed position ``i`` holds a valid frame (``i < count[p]``).
    """

    order: np.ndarray
    valid: np.ndarray

    @staticmethod
    def of(valid: np.ndarray) -> "ValidFrames":
        """Packing of a ``(P, T)`` validity mask."""
        valid = np.asarray(valid, dtype=bool)
        order = np.argsort(~valid, axis=-1, kind="stable")
        return ValidFrames(order, np.take_along_axis(valid, order, axis=-1))

    @property
    def frames(self) -> np.ndarray:
        """``(P, T)`` int original frame of every packed position, -1 where nothing valid is stored."""
        return np.where(self.valid, self.order, -1)

    def _index(self, series: np.ndarray) -> np.ndarray:
        return self.order.reshape(self.order.shape + (1,) * (series.ndim - 2))

    def pack(self, series: np.ndarray) -> np.ndarray:
        """``(P, T, ...)`` series to the packed ``(P, T, ...)``: valid frames first, in time order."""
        return np.take_along_axis(series, self._index(series), axis=1)

    def unpack(self, packed: np.ndarray) -> np.ndarray:
        """Inverse of :meth:`pack`: every packed entry back to its frame."""
        out = np.empty_like(packed)
        np.put_along_axis(out, self._index(packed), packed, axis=1)
        return out


def track_similarities(pred: np.ndarray, true: np.ndarray, valid: np.ndarray,
                       fit: Literal["all", "first_two"] = "all", chunk: int | None = None
                       ) -> tuple[Similarity, np.ndarray]:
    """One Sim(3) per person and chunk of its valid frames, fitted on the points of those frames.

    Chunks cut a track's valid frames (compressed, as WHAM/GVHMR), not the frame axis: chunk ``c`` of
    person ``p`` holds its valid frames number ``c * chunk`` to ``(c + 1) * chunk - 1``, the last one
    shorter.

    Args:
        pred: ``(P, T, N, 3)`` predicted points (joints).
        true: ``(P, T, N, 3)`` true points.
        valid: ``(P, T)`` bool, frames that take part.
        fit: ``"all"`` frames of the chunk (WA-MPJPE) or its ``"first_two"`` (W-MPJPE; one frame when the
            chunk has only one).
        chunk: valid frames per chunk, or None for the whole track.
    Returns:
        the similarities with batch ``(P, C)``, ``C = ceil(T / chunk)``, and ``fitted (P, C)`` bool
        (False for chunks past a track's last valid frame).
    """
    if fit not in ("all", "first_two"):
        raise InputError(f"fit: expected 'all' or 'first_two', got {fit!r}")
    p, t, n, _ = pred.shape
    length = _chunk_length(t, chunk)
    packing = ValidFrames.of(valid)
    frames = _chunked(packing.valid, length)  # (P, C, L)
    if fit == "first_two":
        frames = frames & (np.cumsum(frames, axis=-1) <= 2)
    c = frames.shape[1]
    points_mask = np.repeat(frames, n, axis=-1)  # (P, C, L*N)
    src = _chunked(packing.pack(pred), length).reshape(p, c, length * n, 3)
    dst = _chunked(packing.pack(true), length).reshape(p, c, length * n, 3)
    return fit_similarity(src, dst, points_mask)


def apply_track_similarities(sim: Similarity, points: np.ndarray, valid: np.ndarray,
                             chunk: int | None = None) -> np.ndarray:
    """Apply per-(person, chunk) similarities from :func:`track_similarities` to ``points (P, T, N, 3)``.

    ``valid`` and ``chunk`` must be those of the fit: they say which chunk each frame belongs to. Invalid
    frames take the similarity of the chunk their packed position falls in (the identity past the last
    fitted chunk); they are not scored.
    """
    p, t, n, _ = points.shape
    length = _chunk_length(t, chunk)
    packing = ValidFrames.of(valid)
    chunks = _chunked(packing.pack(points), length)
    c = chunks.shape[1]
    moved = apply_similarity(sim, chunks.reshape(p, c, length * n, 3))
    return packing.unpack(moved.reshape(p, c * length, n, 3)[:, :t])


def _chunk_length(num_frames: int, chunk: int | None) -> int:
    if chunk is None:
        return max(num_frames, 1)
    if int(chunk) < 1:
        raise InputError(f"chunk: must be a positive number of frames or None, got {chunk}")
    return int(chunk)


def _chunked(series: np.ndarray, length: int) -> np.ndarray:
    """``(P, T, ...)`` to ``(P, C, length, ...)``, padding the time axis (zeros / False) to ``C * length``."""
    p, t = series.shape[:2]
    c = max(-(-t // length), 1)
    pad = [(0, 0), (0, c * length - t)] + [(0, 0)] * (series.ndim - 2)
    return np.pad(series, pad).reshape(p, c, length, *series.shape[2:])


def window_mask(valid: np.ndarray, length: int, cut_frames: Sequence[int] | np.ndarray = (),
                include_cuts: bool = True, frames: np.ndarray | None = None) -> np.ndarray:
    """Which windows of ``length`` consecutive entries count.

    Args:
        valid: ``(..., T)`` bool per entry.
        length: entries per window (3 for acceleration, 2 for a displacement...).
        cut_frames: ``(C,)`` first frame of each new shot.
        include_cuts: keep windows that span a cut (frames on both sides of one).
        frames: ``(..., T)`` int video frame of every entry, for packed series (:class:`ValidFrames`);
            entry ``i`` is frame ``i`` when None.
    Returns:
        ``(..., T - length + 1)`` bool, the window starting at entry ``s`` has all entries valid (and,
        unless ``include_cuts``, its first and last frame lie in one shot). Empty when ``T < length``.
    """
    t = valid.shape[-1]
    starts = max(t - length + 1, 0)
    ok = np.ones((*valid.shape[:-1], starts), dtype=bool)
    for k in range(length):
        ok &= valid[..., k:k + starts]
    if not include_cuts and starts:
        frames = np.broadcast_to(np.arange(t), valid.shape) if frames is None else np.asarray(frames)
        shot = np.searchsorted(np.sort(np.asarray(cut_frames, dtype=np.int64)), frames, side="right")
        ok &= shot[..., :starts] == shot[..., length - 1:length - 1 + starts]
    return ok


@dataclass(frozen=True)
class Correspondence:
    """Which predicted identity stands for each true person over the whole video.

    Attributes:
        pred_index: ``(G,)`` int index into the prediction's people, -1 when the true person has none.
        root_distance: ``(G, P)`` mean pelvis distance over co-visible frames, metres (camera frame);
            meaningful where ``covisible > 0``.
        covisible: ``(G, P)`` int, frames where the true person is visible and the prediction exists.
        visible: ``(G, T)`` bool, the true person is in view (the frames that should be scored).
        scored: ``(G, T)`` bool, visible and the paired identity is present: the frames scored for pose.
    """

    pred_index: np.ndarray
    root_distance: np.ndarray
    covisible: np.ndarray
    visible: np.ndarray
    scored: np.ndarray

    @property
    def coverage(self) -> float:
        """Scored / visible frames; NaN when no true person is ever visible."""
        total = int(self.visible.sum())
        return float(self.scored.sum()) / total if total else float("nan")

    def gather(self, pred_series: np.ndarray) -> np.ndarray:
        """``(P, T, ...)`` predicted series to ``(G, T, ...)`` of the paired identities (zeros where unpaired)."""
        out = pred_series[np.clip(self.pred_index, 0, None)] if pred_series.shape[0] else \
            np.zeros((len(self.pred_index), *pred_series.shape[1:]), dtype=pred_series.dtype)
        return np.where((self.pred_index >= 0).reshape(-1, *[1] * (out.ndim - 1)), out, 0)


def pair_people(pred_roots: np.ndarray, pred_valid: np.ndarray, true_roots: np.ndarray,
                true_visible: np.ndarray) -> Correspondence:
    """Pair every true person with one predicted identity: Hungarian on mean root distance.

    Roots must be comparable frame by frame whatever the predicted world frame: the evaluation passes
    each frame's pelvis in that frame's camera coordinates (predicted camera for the prediction, true
    camera for the truth), which needs no alignment and is invariant to the prediction's world frame.

    Args:
        pred_roots: ``(P, T, 3)`` predicted pelvis positions.
        pred_valid: ``(P, T)`` bool.
        true_roots: ``(G, T, 3)`` true pelvis positions.
        true_visible: ``(G, T)`` bool.
    Returns:
        the correspondence; pairs that are never co-visible are dropped.
    """
    if pred_roots.shape[1:] != true_roots.shape[1:]:
        raise InputError(f"pred_roots: shape {pred_roots.shape} does not match true_roots {true_roots.shape} "
                         "beyond the person axis")
    covis = true_visible[:, None, :] & pred_valid[None, :, :]  # (G, P, T)
    dist = np.linalg.norm(true_roots[:, None] - pred_roots[None], axis=-1)
    count = covis.sum(axis=-1)
    mean = np.where(count > 0, np.where(covis, dist, 0.0).sum(axis=-1) / np.maximum(count, 1), 0.0)
    g = true_roots.shape[0]
    pred_index = np.full(g, -1, dtype=np.int64)
    if count.any():
        # A never-co-visible pair costs more than all real pairs together, so Hungarian uses as few
        # as possible; those that remain (more people than possible pairs) are dropped.
        cost = np.where(count > 0, mean, mean[count > 0].sum() + 1.0)
        rows, cols = linear_sum_assignment(cost)
        real = count[rows, cols] > 0
        pred_index[rows[real]] = cols[real]
    has_pair = pred_index >= 0
    scored = true_visible & has_pair[:, None] & pred_valid[np.clip(pred_index, 0, None)] \
        if pred_valid.shape[0] else np.zeros_like(true_visible)
    return Correspondence(pred_index, mean, count, true_visible.copy(), scored & has_pair[:, None])
