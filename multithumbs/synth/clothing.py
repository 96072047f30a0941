"""What the synthetic people wear: colours by body part, drawn per person from the scene's seed, and the
uniform of the dressed-alike pairs.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


# Clothing regions by the SMPL joint that drives a vertex.
_SKIN_PARTS = (12, 15, 20, 21, 22, 23)
_TOP_PARTS = (3, 6, 9, 13, 14, 16, 17)
_SLEEVE_PARTS = (18, 19)
_BOTTOM_PARTS = (0, 1, 2, 4, 5)
_SHOE_PARTS = (7, 8, 10, 11)
_SKIN_TONES = np.array([[0.96, 0.80, 0.69], [0.87, 0.67, 0.52], [0.68, 0.48, 0.34],
                        [0.45, 0.31, 0.22], [0.92, 0.74, 0.60]])
_HAIR = np.array([[0.08, 0.06, 0.05], [0.35, 0.22, 0.12], [0.75, 0.6, 0.35], [0.2, 0.2, 0.2]])
_GARMENTS = np.array([  # saturated and neutral clothing colours, distinct in hue
    [0.80, 0.12, 0.12], [0.10, 0.35, 0.80], [0.12, 0.62, 0.22], [0.95, 0.75, 0.10], [0.55, 0.20, 0.65],
    [0.95, 0.45, 0.10], [0.10, 0.65, 0.70], [0.90, 0.90, 0.88], [0.15, 0.15, 0.18], [0.60, 0.40, 0.25],
    [0.95, 0.55, 0.70], [0.30, 0.30, 0.55],
])

# The dressed-alike pairs' uniform: a charcoal suit, darker trousers, black shoes (all neutral grey).
_UNIFORM_TOP = np.array([0.30, 0.30, 0.30])
_UNIFORM_BOTTOM = np.array([0.20, 0.20, 0.20])
_UNIFORM_SHOES = np.array([0.08, 0.08, 0.08])


@dataclass(frozen=True)
class Clothing:
    """Colours of one person (RGB in [0, 1]).

    Attributes:
        skin, hair, top, sleeves, bottom, shoes: ``(3,)`` each.
    """

    skin: np.ndarray
    hair: np.ndarray
    top: np.ndarray
    sleeves: np.ndarray
    bottom: np.ndarray
    shoes: np.ndarray

    def vertex_colors(self, part_labels: np.ndarray, rest_vertices: np.ndarray, head_top: float) -> np.ndarray:
        """``(V, 3)`` colours from each vertex's part (and hair on the top of the head)."""
        colors = np.tile(self.skin, (part_labels.shape[0], 1))
        for parts, color in ((_TOP_PARTS, self.top), (_SLEEVE_PARTS, self.sleeves),
                             (_BOTTOM_PARTS, self.bottom), (_SHOE_PARTS, self.shoes)):
            colors[np.isin(part_labels, parts)] = color
        head = part_labels == 15
        hair = head & (rest_vertices[:, 1] > head_top - 0.09) | head & (rest_vertices[:, 2] < rest_vertices[head, 2].mean() - 0.04)
        colors[hair] = self.hair
        return colors


def _draw_clothing(rng: np.random.Generator, num_people: int, alike: tuple[tuple[int, int], ...]) -> list[Clothing]:
    tops = rng.permutation(len(_GARMENTS))
    bottoms = rng.permutation(len(_GARMENTS))
    out = []
    for p in range(num_people):
        top = _GARMENTS[tops[p % len(tops)]]
        bottom = _GARMENTS[bottoms[(p + 3) % len(bottoms)]] * 0.7  # trousers a bit darker
        sleeves = top if rng.random() < 0.6 else _SKIN_TONES[rng.integers(len(_SKIN_TONES))]
        out.append(Clothing(_SKIN_TONES[rng.integers(len(_SKIN_TONES))], _HAIR[rng.integers(len(_HAIR))],
                            top, sleeves, bottom, np.array([0.12, 0.1, 0.09]) + 0.3 * rng.random() * np.ones(3)))
    for a, b in alike:
        # A uniform: both wear the same achromatic suit (no hue for a colour descriptor to key on, and grey
        # stays grey however the light falls on it) and the same skin, with shaven heads (hair = skin), so
        # the head looks the same from the front and the back: appearance alone cannot tell them apart,
        # whichever way each faces. The draws above are kept so everybody else dresses as before.
        skin = out[a].skin
        out[a] = out[b] = Clothing(skin, skin, _UNIFORM_TOP, _UNIFORM_TOP, _UNIFORM_BOTTOM, _UNIFORM_SHOES)
    return out
