"""One-frame outliers (a glitched or flashed frame) found before shot detection.

A corrupted frame (a white or coloured block, a full-frame flash) differs from both its neighbours, so a
detector scoring frame-to-frame change sees two large changes in a row: a false cut in mid-shot, and
next to a true cut a cut moved by a frame or two. :func:`spike_score` measures how much a frame stands out
from both neighbours where the neighbours agree with each other, the spike detection index of film
restoration (dirt and blotch detection) taken to the frame. Per pixel and per HSV channel, the excess

    max(0, min(|X - P|, |X - N|) - |P - N|)

is positive only where the frame ``X`` lies outside the range spanned by the previous ``P`` and the next
``N`` frame by more than ``P`` and ``N`` differ; the score is its mean (0..255, the scale of scenedetect's
content score). Motion leaves it small (a moving edge changes ``P`` to ``N`` at least as much as it
changes ``X``), a cut leaves it small (each boundary frame agrees with its own side), a corrupted frame
makes it large wherever the corruption is, also next to a cut.

:func:`without_outliers` streams frames one or two late and replaces each outlier by a neighbour, which
is what the detector then sees. A frame is an outlier when its score reaches ``min_spike`` and is at
least ``isolation`` times its neighbours' scores: fast motion or shaky footage raises the score of
several frames in a row, a glitch of one frame only. A glitch that keeps most of its frame is replaced by
the neighbour it is nearer to (on the last frame of a shot it becomes that shot, on the first frame of
the next shot that shot), a frame unlike both sides (a full-frame flash) by the previous frame. So a cut
next to a glitch stays where the content changes, except that a full-frame flash on the first frame of a
shot moves the cut one frame later: nothing in that frame tells which shot it replaced. The boundary
pair (:func:`~multithumbs.scene.shots.boundary_frames`, which steps past outliers) is the same either way.

Only one-frame outliers are found: two consecutive corrupted frames agree with each other. A genuine
one-frame shot between two shots is an outlier too and is dropped (it is not kept as a shot of its own;
nothing downstream can use a shot of one frame). The first and last frames are never outliers (they
have one neighbour).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterable, Iterator

import cv2
import numpy as np


def to_hsv(bgr: np.ndarray) -> np.ndarray:
    """``(H, W, 3)`` uint8 BGR -> ``(H, W, 3)`` uint8 HSV (OpenCV's ranges, as scenedetect's content score)."""
    return cv2.cvtColor(bgr, cv2.COLOR_BGR2HSV)


def _mean(image: np.ndarray) -> float:
    return float(np.mean(cv2.mean(image)[:3]))


def content_distance(a: np.ndarray, b: np.ndarray) -> float:
    """Mean absolute HSV difference of two ``(H, W, 3)`` uint8 HSV frames: scenedetect's ``content_val``
    with its default weights (hue, saturation, value 1, edges 0)."""
    return _mean(cv2.absdiff(a, b))


def spike_score(prev: np.ndarray, frame: np.ndarray, next_: np.ndarray) -> float:
    """How much ``frame`` stands out from both neighbours where they agree (0..255).

    Args:
        prev, frame, next_: ``(H, W, 3)`` uint8 HSV frames (:func:`to_hsv`) of one size.
    Returns:
        the mean over pixels and channels of ``max(0, min(|X - P|, |X - N|) - |P - N|)``.
    """
    # OpenCV's saturating uint8 subtraction is the max(0, .), and runs several times faster than numpy.
    nearer = cv2.min(cv2.absdiff(frame, prev), cv2.absdiff(frame, next_))
    return _mean(cv2.subtract(nearer, cv2.absdiff(prev, next_)))


def _stand_in(frame: np.ndarray, prev: tuple[np.ndarray, np.ndarray],
              following: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """The ``(bgr, hsv)`` neighbour an outlier (``frame``, HSV) is replaced by: the next frame when the
    outlier is nearer to it than to the previous one and than the two neighbours are to each other (a
    glitch keeping most of the first frame of a shot belongs to that shot), otherwise the previous one
    (also for a frame unlike both sides, a full-frame flash: it is counted with the earlier shot)."""
    to_next = content_distance(frame, following[1])
    if to_next < content_distance(frame, prev[1]) and to_next <= content_distance(prev[1], following[1]):
        return following[0].copy(), following[1]
    return prev[0].copy(), prev[1]


def without_outliers(frames: Iterable[np.ndarray], min_spike: float = 1.0,
                     isolation: float = 2.0) -> Iterator[tuple[np.ndarray, bool]]:
    """Frames in order with every one-frame outlier replaced by its nearer neighbour.

    Frame ``t`` is an outlier when ``s[t] >= min_spike`` and ``s[t] >= isolation * max(s[t-1], s[t+1])``,
    ``s`` being :func:`spike_score`; ``s[t]`` is taken against the frame the consumer got for ``t - 1``
    (a replaced outlier counts as its replacement), ``s[t+1]`` on the frames as they are.

    Args:
        frames: ``(H, W, 3)`` uint8 BGR frames of one size.
        min_spike: smallest spike score of an outlier (content-score units, 0..255).
        isolation: how many times an outlier's score exceeds each neighbour's.
    Yields:
        ``(frame, is_outlier)`` per input frame, in order: the frame itself, or for an outlier a copy
        of a neighbour (:func:`_stand_in`). Up to two frames are held back to decide.
    """
    prev: tuple[np.ndarray, np.ndarray] | None = None  # (bgr, hsv) the consumer got for t - 1
    prev_spike = 0.0  # s[t - 1]
    cached: float | None = None  # s[t] on the frames as they are, from the last step
    ahead: deque[tuple[np.ndarray, np.ndarray]] = deque()  # (bgr, hsv) of t, t + 1, t + 2 as read

    def emit() -> tuple[np.ndarray, bool]:
        nonlocal prev, prev_spike, cached
        current, outlier, spike = ahead.popleft(), False, 0.0
        if prev is not None and ahead:  # the first and last frames have one neighbour only
            hsv, following = current[1], ahead[0]
            # s[t] against an unreplaced t - 1 is the last step's s[t+1]; against a replacement, anew.
            spike = cached if cached is not None else spike_score(prev[1], hsv, following[1])
            after = spike_score(hsv, following[1], ahead[1][1]) if len(ahead) > 1 else None
            outlier = spike >= min_spike and spike >= isolation * max(prev_spike, after or 0.0)
            cached = None if outlier else after
            if outlier:
                current = _stand_in(hsv, prev, following)
        prev, prev_spike = current, spike
        return current[0], outlier

    for frame in frames:
        ahead.append((frame, to_hsv(frame)))
        if len(ahead) == 3:
            yield emit()
    while ahead:
        yield emit()
