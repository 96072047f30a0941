"""The colour of a person: a fixed function of the global id, so a person keeps its colour across cuts,
pictures and exports. Pictures that show a result beside its ground truth colour the result by its paired
truth person instead (:mod:`multithumbs.viz.pairing`)."""

from __future__ import annotations

import colorsys

import numpy as np

_BASE = np.array([  # matplotlib's tab10, in its order: distinct hues, readable on video
    [31, 119, 180], [255, 127, 14], [44, 160, 44], [214, 39, 40], [148, 103, 189],
    [140, 86, 75], [227, 119, 194], [127, 127, 127], [188, 189, 34], [23, 190, 207],
], dtype=np.float64) / 255.0


def id_color(person_id: int) -> np.ndarray:
    """``(3,)`` float RGB in [0, 1] of a global person id: tab10 for ids 0-9, golden-ratio hues beyond."""
    pid = int(person_id)
    if 0 <= pid < len(_BASE):
        return _BASE[pid].copy()
    hue = (0.13 + 0.618033988749895 * pid) % 1.0
    return np.array(colorsys.hsv_to_rgb(hue, 0.75, 0.9))


def id_colors(person_ids) -> np.ndarray:
    """``(P, 3)`` float RGB of every id in ``person_ids (P,)``."""
    ids = np.asarray(person_ids).reshape(-1)
    return np.stack([id_color(i) for i in ids]) if ids.size else np.zeros((0, 3))


def id_color_u8(person_id: int) -> tuple[int, int, int]:
    """``(r, g, b)`` ints in [0, 255] of a global person id."""
    return tuple(int(round(c * 255)) for c in id_color(person_id))  # type: ignore[return-value]
