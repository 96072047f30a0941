"""Text on pictures: a label with a dark outline that lies exactly around its glyphs.

OpenCV's Hershey fonts advance each glyph by an amount that depends on the stroke thickness, so the
usual trick of drawing the text twice (thick and dark, then thin and light) at the same origin puts the
outline's glyphs progressively to the right of the text's: labels read as ghosted ("shot 1 1"). Here
the text is drawn once, into a coverage mask, and the outline is that mask grown by a few pixels, so
the two cannot drift apart whatever the font scale.
"""

from __future__ import annotations

import cv2
import numpy as np

FONT = cv2.FONT_HERSHEY_SIMPLEX


def label_thickness(scale: float) -> int:
    """Stroke width in pixels of text at ``scale`` (1 px up to scale 2)."""
    return max(1, int(scale))


def outline_radius(scale: float) -> int:
    """Outline width in pixels around text at ``scale``: 2 px for small text, growing with the scale."""
    return max(2, int(round(2.5 * scale)))


def text_coverage(text: str, org: tuple[int, int], scale: float, shape: tuple[int, int],
                  thickness: int | None = None) -> np.ndarray:
    """``(H, W)`` float32 in [0, 1]: how much of each pixel the anti-aliased ``text`` covers.

    Parameters
    ----------
    text : str
        The label.
    org : (int, int)
        Bottom-left corner of the text in pixels (OpenCV's ``putText`` origin).
    scale : float
        OpenCV font scale.
    shape : (int, int)
        ``(H, W)`` of the picture.
    thickness : int, optional
        Stroke width (default :func:`label_thickness`).
    """
    canvas = np.zeros(tuple(int(s) for s in shape[:2]), np.uint8)
    cv2.putText(canvas, text, (int(org[0]), int(org[1])), FONT, float(scale), 255,
                label_thickness(scale) if thickness is None else int(thickness), cv2.LINE_AA)
    return canvas.astype(np.float32) / 255.0


def draw_label(image: np.ndarray, text: str, org: tuple[int, int], scale: float,
               color: tuple[int, int, int] = (255, 255, 255), outline_color: tuple[int, int, int] = (0, 0, 0),
               outline: int | None = None) -> np.ndarray:
    """Draw ``text`` with a dark outline on ``image`` (in place) and return it.

    Parameters
    ----------
    image : (H, W, 3) uint8
        The picture (any channel order: colours are given in the same order).
    text, org, scale
        As :func:`text_coverage`.
    color, outline_color : (int, int, int)
        Fill and outline colours.
    outline : int, optional
        Outline width in pixels (default :func:`outline_radius`).

    Returns
    -------
    (H, W, 3) uint8
        ``image``.
    """
    h, w = image.shape[:2]
    (tw, th), base = cv2.getTextSize(text, FONT, float(scale), label_thickness(scale))
    r = outline_radius(scale) if outline is None else int(outline)
    # Work in the label's box only: a full-frame mask per label would cost more than the rest of the frame.
    x0, y0 = max(int(org[0]) - r - 2, 0), max(int(org[1]) - th - r - 2, 0)
    x1, y1 = min(int(org[0]) + tw + r + 2, w), min(int(org[1]) + base + r + 2, h)
    if x0 >= x1 or y0 >= y1:
        return image
    fill = text_coverage(text, (int(org[0]) - x0, int(org[1]) - y0), scale, (y1 - y0, x1 - x0))
    # Grey dilation keeps the anti-aliased edge: the outline is as soft as the glyphs it surrounds.
    ring = cv2.dilate(fill, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1)))
    box = image[y0:y1, x0:x1].astype(np.float32)
    box = box * (1 - ring[..., None]) + np.asarray(outline_color, np.float32) * ring[..., None]
    box = box * (1 - fill[..., None]) + np.asarray(color, np.float32) * fill[..., None]
    image[y0:y1, x0:x1] = np.clip(box + 0.5, 0, 255).astype(np.uint8)
    return image
