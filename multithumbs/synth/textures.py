"""Deterministic procedural textures of a room's surfaces (:mod:`multithumbs.synth.room`), packed into one atlas.

Each surface gets a texture from ``(room seed, surface)``: value noise at several scales plus many random shapes
(planks, rugs, posters, books, doors...), so SIFT finds plenty of distinct, non-repeating features, while the
picture still reads as a room. The floor, the ceiling, the walls and the box faces each have their own painter here;
the building blocks (noise, colours, materials, pictures) are in :mod:`multithumbs.synth.texture_tools`.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import cv2
import numpy as np

from multithumbs.synth.room import NUM_ROOM_SURFACES, TEXEL_SIZE, Room, Surface, room_surfaces
from multithumbs.synth.texture_tools import (_fbm, _fill, _framed_picture, _hsv, _material, _material_image, _modulate,
                                             _noise, _picture, _place, _random_colour, _rng, _scatter_rects, _shade)


def _floor_texture(seed: int, h: int, w: int) -> np.ndarray:
    rng = _rng(seed, 1, 0)
    img = np.empty((h, w, 3), np.float32)
    if rng.uniform() < 0.7:
        # Wooden planks of random widths and lengths: grain along the plank, a tone per plank, dark joints.
        hue, sat, val = rng.uniform(0.05, 0.1), rng.uniform(0.4, 0.7), rng.uniform(0.4, 0.7)
        grain = _noise(rng, h, w, 1.0, 20.0) * 0.7 + _noise(rng, h, w, 2.5, 70.0) * 0.5
        y = 0
        while y < h:
            ph = int(rng.uniform(0.12, 0.2) / TEXEL_SIZE)
            x = -int(rng.uniform(0, 1.5) / TEXEL_SIZE)
            while x < w:
                pw = int(rng.uniform(0.6, 1.8) / TEXEL_SIZE)
                tone = _hsv(hue + rng.normal(0, 0.012), sat + rng.normal(0, 0.08), val * rng.uniform(0.75, 1.2))
                _fill(img, x, y, x + pw, y + ph, tone)
                cv2.line(img, (x, y), (x, y + ph), _hsv(hue, sat, val * 0.35), 1)
                for _ in range(int(rng.poisson(1.5))):  # knots
                    cv2.ellipse(img, (int(x + rng.uniform(0, pw)), int(y + rng.uniform(0, ph))),
                                (int(rng.integers(2, 4)), 1), 0, 0, 360, _hsv(hue, sat, val * 0.6), -1)
                x += pw
            cv2.line(img, (0, y), (w, y), _hsv(hue, sat, val * 0.35), 1)
            y += ph
        img = _modulate(img, grain + 0.5 * _fbm(rng, h, w, (60, 12)), 0.1)
    else:
        # Stone tiles: a strongly varying tone per tile with veins and speckle, grout lines.
        tile = int(rng.uniform(0.3, 0.6) / TEXEL_SIZE)
        base = _hsv(rng.choice([0.03, 0.08, 0.12, 0.58]), rng.uniform(0.03, 0.35), rng.uniform(0.45, 0.75))
        for ty in range(0, h, tile):
            for tx in range(0, w, tile):
                _fill(img, tx, ty, tx + tile, ty + tile, _shade(base, rng.uniform(0.7, 1.25)))
        veins = np.abs(_fbm(rng, h, w, (30, 10, 3)))
        img = _modulate(img, -np.exp(-8 * veins) + 0.3 * _fbm(rng, h, w, (4, 2)), 0.25)
        # Terrazzo chips: small stones of a few tones scattered at random (non-repeating detail).
        chips = [_shade(base, f) for f in (0.45, 0.7, 1.35)]
        chips.append(_hsv(rng.uniform(0.02, 0.12), 0.4, rng.uniform(0.35, 0.7)))
        for _ in range(int(w * h * TEXEL_SIZE ** 2 * 60)):
            cv2.ellipse(img, (int(rng.uniform(0, w)), int(rng.uniform(0, h))),
                        (int(rng.integers(1, 4)), int(rng.integers(1, 3))), rng.uniform(0, 180), 0, 360,
                        chips[int(rng.integers(len(chips)))], -1)
        grout = _shade(base, 0.5)
        for k in range(0, max(h, w), tile):
            cv2.line(img, (0, k), (w, k), grout, 1)
            cv2.line(img, (k, 0), (k, h), grout, 1)
    # Rugs: a border, a field and a motif of many small shapes.
    for _ in range(int(rng.integers(1, 3))):
        rw, rh = int(rng.uniform(1.5, 3.0) / TEXEL_SIZE), int(rng.uniform(1.0, 2.2) / TEXEL_SIZE)
        rw, rh = min(rw, w - 2), min(rh, h - 2)
        rug = np.empty((rh, rw, 3), np.float32)
        field, border = _random_colour(rng, val=(0.3, 0.8)), _random_colour(rng, val=(0.2, 0.7))
        rug[:] = border
        b = max(2, int(0.12 / TEXEL_SIZE))
        rug[b:rh - b, b:rw - b] = field
        for _ in range(int(rng.integers(40, 120))):
            c = _random_colour(rng)
            x, y, s = rng.uniform(b, rw - b), rng.uniform(b, rh - b), rng.uniform(2, 12)
            if rng.uniform() < 0.5:
                cv2.circle(rug, (int(x), int(y)), int(s / 2) + 1, c, -1)
            else:
                diamond = np.array([[x, y - s], [x + s, y], [x, y + s], [x - s, y]], np.int32)
                cv2.fillPoly(rug, [diamond], c)
        rug = _modulate(rug, _noise(rng, rh, rw, 1.0), 0.08)
        _place(img, rug, int(rng.uniform(0, w - rw)), int(rng.uniform(0, h - rh)))
    return _modulate(img, _noise(rng, h, w, 30.0), 0.05)


def _wall_texture(seed: int, surface_id: int, h: int, w: int) -> np.ndarray:
    room_rng = _rng(seed, 1, 1)  # shared by all walls: one paint colour per room
    paint = _hsv(room_rng.uniform(), room_rng.uniform(0.03, 0.25), room_rng.uniform(0.78, 0.95))
    skirting = _hsv(0.08, room_rng.uniform(0, 0.5), room_rng.uniform(0.3, 0.95))
    door_wall, window_wall = room_rng.permutation(4)[:2] + 2
    rng = _rng(seed, 1, surface_id)
    img = np.empty((h, w, 3), np.float32)
    img[:] = paint
    # Sponge-painted plaster: broad shading plus 5-10 cm blotches that give SIFT something everywhere.
    img = _modulate(img, 0.5 * _noise(rng, h, w, 60.0) + _fbm(rng, h, w, (6, 3, 1.5), falloff=0.7), 0.07)
    if rng.uniform() < 0.5:
        # Wallpaper: small motifs (dots, leaves, rings, stars) at random places, sizes and tones.
        tones = [_shade(paint, rng.uniform(0.55, 0.85)) for _ in range(2)]
        tones.append(_random_colour(rng, (0.15, 0.4), (0.4, 0.8)))
        for _ in range(int(w * h * TEXEL_SIZE ** 2 * rng.uniform(15, 30))):
            x, y, r = int(rng.uniform(0, w)), int(rng.uniform(0, h)), int(rng.uniform(1.5, 5))
            colour, shape = tones[int(rng.integers(len(tones)))], rng.integers(4)
            if shape == 0:
                cv2.circle(img, (x, y), r, colour, -1)
            elif shape == 1:
                cv2.ellipse(img, (x, y), (r + 2, max(1, r // 2)), rng.uniform(0, 180), 0, 360, colour, -1)
            elif shape == 2:
                cv2.circle(img, (x, y), r + 1, colour, 1)
            else:
                angles = np.linspace(0, 2 * np.pi, 10, endpoint=False) + rng.uniform(0, np.pi)
                radii = (r + 2) * np.where(np.arange(10) % 2 == 0, 1.0, 0.4)
                star = np.stack([x + radii * np.cos(angles), y + radii * np.sin(angles)], axis=-1)
                cv2.fillPoly(img, [star.astype(np.int32)], colour)
    floor_row = h  # texture rows run down from the ceiling
    m = lambda metres: int(round(metres / TEXEL_SIZE))
    taken: list[tuple[int, int, int, int]] = []
    _fill(img, 0, floor_row - m(0.1), w, floor_row, skirting)
    cv2.line(img, (0, floor_row - m(0.1)), (w, floor_row - m(0.1)), _shade(skirting, 0.6), 1)
    if surface_id == door_wall and w > m(1.4):
        dw, dh = m(0.9), min(m(2.05), h - m(0.2))
        x0 = int(rng.uniform(m(0.2), w - dw - m(0.2)))
        y0 = floor_row - dh
        door = _material_image(rng, dh, dw, ("wood", _hsv(0.07, 0.6, rng.uniform(0.3, 0.6))))
        for px0, py0, px1, py1 in ((0.15, 0.08, 0.85, 0.45), (0.15, 0.55, 0.85, 0.92)):
            cv2.rectangle(door, (int(px0 * dw), int(py0 * dh)), (int(px1 * dw), int(py1 * dh)),
                          _shade(door[0, 0], 0.6), 1)
        cv2.circle(door, (int(0.88 * dw), int(0.5 * dh)), 2, (0.8, 0.75, 0.5), -1)
        frame = np.empty((dh + m(0.06), dw + 2 * m(0.06), 3), np.float32)
        frame[:] = _shade(skirting, 0.9)
        _place(frame, door, m(0.06), m(0.06))
        _place(img, frame, x0 - m(0.06), y0 - m(0.06))
        taken.append((x0 - m(0.06), y0 - m(0.06), dw + m(0.12), dh + m(0.06)))
    if surface_id == window_wall and w > m(2.0):
        ww, wh = m(rng.uniform(1.2, 1.8)), m(rng.uniform(1.0, 1.3))
        x0, y0 = int(rng.uniform(m(0.2), w - ww - m(0.2))), floor_row - m(0.9) - wh
        ramp = np.linspace(0, 1, wh, dtype=np.float32)[:, None, None]
        window = np.array(_hsv(0.58, 0.55, 0.85)) * (1 - ramp) + np.array(_hsv(0.55, 0.15, 1.0)) * ramp
        window = window * np.ones((1, ww, 1), np.float32)
        clouds = np.clip(_fbm(rng, wh, ww, (25, 8, 3)) - 0.2, 0, 1)[..., None]
        window = window * (1 - clouds) + clouds
        xs = np.linspace(0, ww, 12)
        skyline = np.array([[0, wh], *zip(xs, wh * rng.uniform(0.55, 0.9, 12)), [ww, wh]], np.int32)
        cv2.fillPoly(window, [skyline], _hsv(0.6, 0.15, 0.45))
        fc, bar = (0.92, 0.92, 0.9), max(1, m(0.04))
        for box in ((0, 0, ww, bar), (0, wh - bar, ww, wh), (0, 0, bar, wh), (ww - bar, 0, ww, wh),
                    (ww // 2 - bar // 2, 0, ww // 2 + bar // 2, wh)):
            _fill(window, *box, fc)
        _place(img, window, x0, y0)
        _fill(img, x0 - m(0.05), y0 + wh, x0 + ww + m(0.05), y0 + wh + m(0.04), fc)  # sill
        taken.append((x0, y0, ww, wh))
    # Pictures and posters at eye height, then small fittings (switches, sockets, a clock).
    top = h * TEXEL_SIZE  # wall height: rows count down from the ceiling
    for x0, y0, pw, ph in _scatter_rects(rng, h, w, ((0.35, 1.2), (0.3, 0.9)), (top - 2.2, top - 1.4),
                                         count=max(2, int(w * TEXEL_SIZE / 0.7)), taken=taken):
        _place(img, _framed_picture(rng, ph, pw), x0, y0)
        taken.append((x0, y0, pw, ph))
    for x0, y0, pw, ph in _scatter_rects(rng, h, w, ((0.1, 0.35), (0.12, 0.4)), (top - 1.9, top - 0.5),
                                         count=int(rng.integers(4, 12)), taken=taken):
        _place(img, _picture(rng, ph, pw), x0, y0)  # unframed notes and small prints
        taken.append((x0, y0, pw, ph))
    for _ in range(int(rng.integers(1, 4))):
        x, y = int(rng.uniform(0, w - m(0.1))), floor_row - m(rng.choice([0.3, 1.1]))
        _fill(img, x, y, x + m(0.08), y + m(0.08), (0.93, 0.93, 0.9))
        cv2.rectangle(img, (x, y), (x + m(0.08), y + m(0.08)), (0.6, 0.6, 0.6), 1)
        cv2.circle(img, (x + m(0.04), y + m(0.04)), 1, (0.3, 0.3, 0.3), -1)
    return img


def _ceiling_texture(seed: int, h: int, w: int) -> np.ndarray:
    rng = _rng(seed, 1, 2)
    img = np.empty((h, w, 3), np.float32)
    img[:] = _hsv(0.1, rng.uniform(0, 0.06), rng.uniform(0.85, 0.95))
    img = _modulate(img, _fbm(rng, h, w, (60, 15, 4, 1.5)), 0.05)
    m = lambda metres: int(round(metres / TEXEL_SIZE))
    for x0, y0, pw, ph in _scatter_rects(rng, h, w, ((0.6, 1.2), (0.3, 0.6)), (0.3, h * TEXEL_SIZE - 0.6),
                                         count=int(rng.integers(3, 7)), taken=[]):
        _fill(img, x0, y0, x0 + pw, y0 + ph, (0.75, 0.75, 0.75))
        _fill(img, x0 + 2, y0 + 2, x0 + pw - 2, y0 + ph - 2, (1.0, 1.0, 0.97))
        for k in range(1, 4):
            cv2.line(img, (x0 + k * pw // 4, y0), (x0 + k * pw // 4, y0 + ph), (0.8, 0.8, 0.78), 1)
    for _ in range(int(rng.integers(2, 6))):
        centre = (int(rng.uniform(0, w)), int(rng.uniform(0, h)))
        cv2.circle(img, centre, m(rng.uniform(0.04, 0.1)), (0.97, 0.97, 0.97), -1)  # smoke detectors
    return img


def _box_face_texture(seed: int, surface: Surface, h: int, w: int) -> np.ndarray:
    box_index = (surface.surface_id - NUM_ROOM_SURFACES) // 6
    material = _material(_rng(seed, 2, box_index))  # shared by the box's faces
    rng = _rng(seed, 3, surface.surface_id)
    img = _material_image(rng, h, w, material)
    kind, m = surface.kind, (lambda metres: max(1, int(round(metres / TEXEL_SIZE))))
    vertical = abs(surface.normal[2]) < 0.5
    front = vertical and surface.extent[0] >= 0.6  # the long faces carry the detail
    dark = _shade(material[1], 0.5)
    if kind == "shelf" and front:
        # Boards and rows of books of random widths, heights and colours.
        y = m(0.05)
        while y < h - m(0.3):
            gap = m(rng.uniform(0.3, 0.42))
            x = m(0.04)
            while x < w - m(0.06):
                bw = m(rng.uniform(0.02, 0.06))
                if rng.uniform() < 0.1:  # a gap in the row
                    x += m(rng.uniform(0.05, 0.2))
                    continue
                bh = int(gap * rng.uniform(0.6, 0.95))
                colour = _random_colour(rng, val=(0.2, 0.85))
                _fill(img, x, y + gap - bh, x + bw - 1, y + gap, colour)
                if bh > 8:
                    _fill(img, x, y + gap - int(0.7 * bh), x + bw - 1, y + gap - int(0.6 * bh), _shade(colour, 1.6))
                x += bw
            y += gap
            _fill(img, 0, y, w, y + m(0.025), _shade(material[1], 1.1))
            y += m(0.025)
    elif kind == "cabinet" and front:
        columns = int(rng.integers(1, 4))
        for c in range(columns):
            x0, x1 = c * w // columns + 2, (c + 1) * w // columns - 2
            if rng.uniform() < 0.5:  # a stack of drawers
                rows = int(rng.integers(2, 5))
                for r in range(rows):
                    y0, y1 = r * h // rows + 2, (r + 1) * h // rows - 2
                    cv2.rectangle(img, (x0, y0), (x1, y1), dark, 1)
                    mid = (x0 + x1) // 2
                    _fill(img, mid - m(0.06), y0 + m(0.04), mid + m(0.06), y0 + m(0.055), (0.75, 0.75, 0.72))
            else:  # a door
                cv2.rectangle(img, (x0, 2), (x1, h - 3), dark, 1)
                cv2.rectangle(img, (x0 + m(0.05), m(0.07)), (x1 - m(0.05), h - m(0.07)), _shade(material[1], 0.8), 1)
                _fill(img, x1 - m(0.05), h // 3, x1 - m(0.035), h // 3 + m(0.12), (0.75, 0.75, 0.72))
        for x0, y0, pw, ph in _scatter_rects(rng, h, w, ((0.06, 0.2), (0.06, 0.2)), (0.0, h * TEXEL_SIZE),
                                             count=int(rng.integers(0, 4)), taken=[]):
            _place(img, _picture(rng, ph, pw), x0, y0)  # stickers
    elif kind == "table" and front:
        _fill(img, 0, 0, w, m(0.04), _shade(material[1], 1.2))
        _fill(img, 0, h - m(0.1), w, h, _shade(material[1], 0.6))
        for k in range(1, int(rng.integers(2, 5))):
            cv2.line(img, (k * w // 4, m(0.04)), (k * w // 4, h - m(0.1)), dark, 1)
    elif kind == "panel" and front:
        # A notice board: cork with pinned papers and pins.
        cork = _modulate(np.full((h, w, 3), _hsv(0.08, 0.55, 0.62), np.float32),
                         _noise(rng, h, w, 1.0) + 0.5 * _noise(rng, h, w, 4.0), 0.15)
        border = m(0.04)
        img[border:h - border, border:w - border] = cork[border:h - border, border:w - border]
        for x0, y0, pw, ph in _scatter_rects(rng, h, w, ((0.12, 0.45), (0.15, 0.45)), (0.1, h * TEXEL_SIZE - 0.2),
                                             count=int(rng.integers(8, 18)), taken=[]):
            _place(img, _picture(rng, ph, pw), x0, y0)
            cv2.circle(img, (x0 + pw // 2, y0 + 2), 2, _random_colour(rng, sat=(0.8, 1), val=(0.7, 1)), -1)
    elif vertical and kind == "pillar":
        img = _modulate(img, _noise(rng, h, w, 1.0) + 0.6 * _noise(rng, h, w, 3.0), 0.08)
        top = h * TEXEL_SIZE
        for x0, y0, pw, ph in _scatter_rects(rng, h, w, ((0.15, 0.3), (0.2, 0.4)), (top - 2.0, top - 1.2),
                                             count=1, taken=[]):
            _place(img, _picture(rng, ph, pw), x0, y0)
    elif not vertical and surface.normal[2] > 0:
        # Tops: a few objects (papers, books, a plant pot, a mug) seen from above.
        for _ in range(int(rng.integers(1, 6))):
            x, y, s = rng.uniform(0, w), rng.uniform(0, h), m(rng.uniform(0.06, 0.3))
            if rng.uniform() < 0.5:
                _place(img, _picture(rng, s, int(s * rng.uniform(0.7, 1.4))), int(x), int(y))
            else:
                cv2.circle(img, (int(x), int(y)), max(1, s // 3), _random_colour(rng), -1)
                cv2.circle(img, (int(x), int(y)), max(1, s // 5), _random_colour(rng), -1)
    if vertical:
        # A darker edge outline makes box corners visible against same-coloured neighbours.
        cv2.rectangle(img, (0, 0), (w - 1, h - 1), _shade(material[1], 0.75), 1)
    return img


@functools.lru_cache(maxsize=1024)
def surface_texture(seed: int, surface: Surface) -> np.ndarray:
    """``(rows, cols, 3)`` uint8 RGB texture of ``surface`` in a room with texture ``seed`` (read-only, cached).

    Texel ``(r, c)`` covers ``origin + [c, c+1] * TEXEL_SIZE * u_axis + [r, r+1] * TEXEL_SIZE * v_axis``.
    Deterministic from ``(seed, surface)``.
    """
    h, w = surface.texture_shape
    if surface.kind == "floor":
        img = _floor_texture(seed, h, w)
    elif surface.kind == "ceiling":
        img = _ceiling_texture(seed, h, w)
    elif surface.kind == "wall":
        img = _wall_texture(seed, surface.surface_id, h, w)
    else:
        img = _box_face_texture(seed, surface, h, w)
    out = np.clip(img * 255.0 + 0.5, 0, 255).astype(np.uint8)
    out.flags.writeable = False
    return out


@dataclass(frozen=True)
class TextureAtlas:
    """All textures of a room packed into one image, so a frame samples them in one ``cv2.remap``.

    Attributes:
        image: ``(Ha, Wa, 3)`` uint8 atlas; each texture has a one-texel replicated border.
        offsets: ``(S, 2)`` int, atlas column and row of texel ``(0, 0)`` of each surface.
        shapes: ``(S, 2)`` int, ``(rows, cols)`` of each surface's texture.
    """

    image: np.ndarray
    offsets: np.ndarray
    shapes: np.ndarray


@functools.lru_cache(maxsize=8)
def texture_atlas(room: Room, atlas_width: int = 2048) -> TextureAtlas:
    """The textures of every surface of ``room`` shelf-packed into one atlas (cached per room)."""
    textures = [cv2.copyMakeBorder(surface_texture(room.seed, s), 1, 1, 1, 1, cv2.BORDER_REPLICATE)
                for s in room_surfaces(room)]
    width = max(atlas_width, max(t.shape[1] for t in textures))
    order = sorted(range(len(textures)), key=lambda i: -textures[i].shape[0])
    offsets = np.zeros((len(textures), 2), np.int64)
    x = y = shelf = 0
    for i in order:
        th, tw = textures[i].shape[:2]
        if x + tw > width:
            x, y, shelf = 0, y + shelf, 0
        offsets[i] = (x, y)
        x, shelf = x + tw, max(shelf, th)
    image = np.zeros((y + shelf, width, 3), np.uint8)
    for (ox, oy), tex in zip(offsets, textures):
        image[oy:oy + tex.shape[0], ox:ox + tex.shape[1]] = tex
    image.flags.writeable = False
    shapes = np.array([t.shape[:2] for t in textures], np.int64) - 2
    return TextureAtlas(image, offsets + 1, shapes)
