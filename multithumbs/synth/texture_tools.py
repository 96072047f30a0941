"""Building blocks of the procedural room textures (:mod:`multithumbs.synth.textures`): seeded value noise,
colours, furniture materials, pictures (posters, paintings, papers) and pasting patches.

Images are ``(h, w, 3)`` float32 RGB, about ``[0, 1]``, sized in texels of
:data:`multithumbs.synth.room.TEXEL_SIZE`. The helpers draw randomness only from the generator they are given
(:func:`_rng` makes one from a seed key), so a texture is deterministic from its seed.
"""

from __future__ import annotations

import colorsys

import cv2
import numpy as np

from multithumbs.synth.room import TEXEL_SIZE


def _rng(*key: int) -> np.random.Generator:
    return np.random.default_rng([int(k) for k in key])


def _noise(rng: np.random.Generator, h: int, w: int, cell_v: float, cell_u: float | None = None) -> np.ndarray:
    """``(h, w)`` float32 value noise of roughly unit variance with features ``cell_v x cell_u`` texels."""
    cell_u = cell_v if cell_u is None else cell_u
    gh, gw = int(np.ceil(h / cell_v)) + 3, int(np.ceil(w / cell_u)) + 3
    grid = rng.standard_normal((gh, gw)).astype(np.float32)
    if cell_v <= 1 and cell_u <= 1:
        return grid[:h, :w]
    big = cv2.resize(grid, (int(round(gw * cell_u)), int(round(gh * cell_v))), interpolation=cv2.INTER_CUBIC)
    return big[:h, :w] / max(float(big.std()), 1e-6)


def _fbm(rng: np.random.Generator, h: int, w: int, cells=(48, 16, 6, 2), falloff: float = 0.6) -> np.ndarray:
    """``(h, w)`` multi-scale noise: octaves at ``cells`` texels, each ``falloff`` times the previous amplitude."""
    out = np.zeros((h, w), np.float32)
    amp, total = 1.0, 0.0
    for cell in cells:
        out += amp * _noise(rng, h, w, cell)
        total += amp ** 2
        amp *= falloff
    return out / np.sqrt(total)


def _hsv(h: float, s: float, v: float) -> tuple[float, float, float]:
    return tuple(float(c) for c in colorsys.hsv_to_rgb(h % 1.0, float(np.clip(s, 0, 1)), float(np.clip(v, 0, 1))))


def _random_colour(rng: np.random.Generator, sat=(0.3, 0.95), val=(0.25, 0.95)) -> tuple[float, float, float]:
    return _hsv(rng.uniform(), rng.uniform(*sat), rng.uniform(*val))


def _shade(colour, factor: float) -> tuple[float, float, float]:
    return tuple(float(np.clip(c * factor, 0, 1)) for c in colour)


def _modulate(img: np.ndarray, noise: np.ndarray, amount: float) -> np.ndarray:
    """Multiply the image by ``1 + amount * noise`` (brightness variation that keeps hue)."""
    return img * (1.0 + amount * noise)[..., None]


def _fill(img: np.ndarray, x0, y0, x1, y1, colour) -> None:
    cv2.rectangle(img, (int(x0), int(y0)), (int(x1), int(y1)), colour, -1)


def _material(rng: np.random.Generator) -> tuple[str, tuple[float, float, float]]:
    """A furniture material: ``("wood" | "paint" | "metal", base colour)``."""
    kind = rng.choice(["wood", "wood", "paint", "paint", "metal"])
    if kind == "wood":
        return "wood", _hsv(rng.uniform(0.05, 0.1), rng.uniform(0.45, 0.75), rng.uniform(0.35, 0.75))
    if kind == "paint":
        return "paint", _random_colour(rng, sat=(0.15, 0.7), val=(0.45, 0.9))
    grey = rng.uniform(0.45, 0.7)
    return "metal", (grey, grey, grey * rng.uniform(1.0, 1.1))


def _material_image(rng: np.random.Generator, h: int, w: int, material: tuple[str, tuple]) -> np.ndarray:
    """``(h, w, 3)`` float image of a plain material with its grain."""
    name, colour = material
    img = np.empty((h, w, 3), np.float32)
    img[:] = colour
    if name == "wood":
        # Grain: noise stretched along the columns, plus broad tone variation.
        grain = _noise(rng, h, w, 1.0, 24.0) * 0.6 + _noise(rng, h, w, 3.0, 60.0) * 0.4
        return _modulate(img, grain + 0.5 * _fbm(rng, h, w, (40, 8)), 0.12)
    if name == "metal":
        return _modulate(img, _noise(rng, h, w, 1.0, 30.0) + 0.5 * _noise(rng, h, w, 20.0), 0.06)
    return _modulate(img, _fbm(rng, h, w, (40, 10, 3, 1)), 0.05)


def _picture(rng: np.random.Generator, h: int, w: int) -> np.ndarray:
    """``(h, w, 3)`` float picture for a poster, painting or paper: abstract art, landscape or a text page."""
    style = rng.choice(["abstract", "abstract", "landscape", "document", "blobs"])
    img = np.empty((max(h, 0), max(w, 0), 3), np.float32)
    if h < 4 or w < 4:  # too small for any detail
        img[:] = _random_colour(rng)
        return img
    palette = [_random_colour(rng) for _ in range(int(rng.integers(3, 7)))]
    scale = max(min(h, w), 4)
    if style == "landscape":
        sky_top, sky_bottom = np.array(_hsv(rng.uniform(0.53, 0.65), 0.6, 0.9)), np.array(_hsv(0.1, 0.2, 1.0))
        ramp = np.linspace(0, 1, h, dtype=np.float32)[:, None, None]
        img[:] = sky_top * (1 - ramp) + sky_bottom * ramp
        cv2.circle(img, (int(rng.uniform(0, w)), int(rng.uniform(0.1, 0.4) * h)), int(0.08 * scale + 1),
                   _hsv(rng.uniform(0.08, 0.15), 0.8, 1.0), -1)
        for layer in range(int(rng.integers(2, 5))):
            base = h * (0.45 + 0.15 * layer)
            xs = np.linspace(0, w, 8)
            ys = base + rng.uniform(-0.2, 0.1, 8) * h
            poly = np.array([[0, h], *zip(xs, ys), [w, h]], np.int32)
            cv2.fillPoly(img, [poly], _hsv(rng.uniform(0.2, 0.4), rng.uniform(0.4, 0.8), 0.7 - 0.15 * layer))
        for _ in range(int(rng.integers(3, 12))):
            x, y = rng.uniform(0, w), rng.uniform(0.55, 1.0) * h
            s = rng.uniform(0.03, 0.1) * scale + 1
            tri = np.array([[x - s, y], [x + s, y], [x, y - 3 * s]], np.int32)
            cv2.fillPoly(img, [tri], _hsv(rng.uniform(0.25, 0.4), 0.7, rng.uniform(0.2, 0.5)))
    elif style == "document":
        img[:] = _hsv(rng.uniform(0.1, 0.15), rng.uniform(0.0, 0.12), rng.uniform(0.88, 0.98))
        _fill(img, 0, 0, w, rng.uniform(0.08, 0.2) * h, palette[0])
        y = 0.25 * h
        while y < 0.92 * h:
            x = 0.08 * w
            line_end = rng.uniform(0.55, 0.92) * w
            while x < line_end:
                word = rng.uniform(0.03, 0.12) * w
                _fill(img, x, y, min(x + word, line_end), y + max(1, 0.02 * h), (0.12, 0.12, 0.14))
                x += word + 0.03 * w
            y += rng.uniform(0.04, 0.07) * h
        if rng.uniform() < 0.6:  # an illustration
            x0, y0 = int(rng.uniform(0.4, 0.5) * w), int(rng.uniform(0.3, 0.6) * h)
            _place(img, _picture(rng, int(0.3 * h), int(0.45 * w)), x0, y0)
    else:
        img[:] = palette[0]
        if style == "blobs":
            ramp = np.array(palette[1]) - np.array(palette[0])
            img += ramp * np.clip(0.5 + 0.5 * _noise(rng, h, w, max(2.0, scale / 4)), 0, 1)[..., None]
        for _ in range(int(rng.integers(15, 60))):
            colour = palette[int(rng.integers(len(palette)))]
            x, y = rng.uniform(0, w), rng.uniform(0, h)
            s = rng.uniform(0.03, 0.3) * scale + 1
            shape = rng.integers(4)
            if shape == 0:
                cv2.circle(img, (int(x), int(y)), int(s / 2), colour, -1 if rng.uniform() < 0.7 else 2)
            elif shape == 1:
                _fill(img, x, y, x + s * rng.uniform(0.3, 2), y + s * rng.uniform(0.3, 2), colour)
            elif shape == 2:
                pts = np.array([x, y]) + rng.uniform(-s, s, (int(rng.integers(3, 6)), 2))
                cv2.fillPoly(img, [pts.astype(np.int32)], colour)
            else:
                cv2.line(img, (int(x), int(y)), (int(x + rng.uniform(-2, 2) * s), int(y + rng.uniform(-2, 2) * s)),
                         colour, int(rng.integers(1, 4)))
    return np.clip(_modulate(img, _noise(rng, h, w, 1.0), 0.03), 0, 1)


def _framed_picture(rng: np.random.Generator, h: int, w: int) -> np.ndarray:
    """A picture with a frame (wood, black, white or metal) 2 to 4 cm wide."""
    img = np.empty((h, w, 3), np.float32)
    img[:] = _hsv(rng.uniform(0.05, 0.1), rng.uniform(0, 0.6), rng.choice([0.1, 0.45, 0.95, 0.6]))
    b = int(np.clip(rng.uniform(0.02, 0.04) / TEXEL_SIZE, 1, min(h, w) // 4))
    if rng.uniform() < 0.4:  # white mat inside the frame
        img[b:h - b, b:w - b] = (0.95, 0.95, 0.93)
        b2 = b + max(1, int(0.08 * min(h, w)))
        img[b2:h - b2, b2:w - b2] = _picture(rng, h - 2 * b2, w - 2 * b2)
    else:
        img[b:h - b, b:w - b] = _picture(rng, h - 2 * b, w - 2 * b)
    return img


def _place(img: np.ndarray, patch: np.ndarray, x0: int, y0: int) -> None:
    """Paste ``patch`` at column ``x0``, row ``y0``, clipped to the image."""
    h, w = img.shape[:2]
    ph, pw = patch.shape[:2]
    xa, ya, xb, yb = max(0, x0), max(0, y0), min(w, x0 + pw), min(h, y0 + ph)
    if xb > xa and yb > ya:
        img[ya:yb, xa:xb] = patch[ya - y0:yb - y0, xa - x0:xb - x0]


def _scatter_rects(rng: np.random.Generator, h: int, w: int, sizes_m, rows_m, count: int,
                   taken: list) -> list[tuple[int, int, int, int]]:
    """Up to ``count`` non-overlapping rectangles ``(x0, y0, pw, ph)`` in texels, avoiding ``taken``."""
    out = []
    for _ in range(count * 20):
        if len(out) == count:
            break
        pw = int(rng.uniform(*sizes_m[0]) / TEXEL_SIZE)
        ph = int(rng.uniform(*sizes_m[1]) / TEXEL_SIZE)
        if pw < 4 or ph < 4 or pw > w - 2 or ph > h - 2:
            continue
        x0 = int(rng.uniform(0, w - pw))
        y0 = int(rng.uniform(*rows_m) / TEXEL_SIZE)
        y0 = int(np.clip(y0, 0, h - ph))
        margin = int(0.08 / TEXEL_SIZE)
        if any(x0 < tx + tw + margin and tx < x0 + pw + margin and y0 < ty + th + margin and ty < y0 + ph + margin
               for tx, ty, tw, th in taken + out):
            continue
        out.append((x0, y0, pw, ph))
    return out
