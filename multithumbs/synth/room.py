"""Procedural textured rooms for the synthetic benchmark: geometry and deterministic textures.

World frame: metric, +z up, floor at ``z = 0`` (:mod:`multithumbs.conventions`). A room spans
``x in [-w/2, w/2]``, ``y in [-d/2, d/2]``, ``z in [0, h]`` and holds axis-aligned :class:`Box` es
(furniture, shelves, free-standing panels, pillars) near its walls, leaving the centre free for people.

Every flat face is a :class:`Surface` with an id:
``0`` floor, ``1`` ceiling, ``2..5`` the walls at ``x = -w/2, x = +w/2, y = -d/2, y = +d/2``, then six
per box, ``6 + 6 i + 2 a + s`` for the face of box ``i`` on axis ``a`` (0 x, 1 y, 2 z) at its low
(``s = 0``) or high (``s = 1``) side. Each surface gets a texture from ``(room seed, surface)``: value
noise at several scales plus many random shapes (planks, rugs, posters, books, doors...), so SIFT finds
plenty of distinct, non-repeating features, while the picture still reads as a room.
"""

from __future__ import annotations

import colorsys
import functools
from dataclasses import dataclass

import cv2
import numpy as np

from multithumbs.errors import InputError

TEXEL_SIZE = 0.015
"""Texture resolution in metres per texel: about one pixel at 5 m for a 640-pixel-wide, 65-degree view."""

BOX_KINDS = ("cabinet", "shelf", "table", "panel", "pillar")
"""What a box can be; the kind decides its size range, placement and textures."""

NUM_ROOM_SURFACES = 6
"""Floor, ceiling and four walls come before the box faces in the surface ids."""


@dataclass(frozen=True)
class Box:
    """An axis-aligned box in the room: a cabinet, shelf, table, free-standing panel (thin) or pillar.

    Coordinates are tuples rather than arrays so that rooms are hashable and their textures cacheable.

    Attributes:
        centre: ``(3,)`` centre in the world frame, metres.
        size: ``(3,)`` full extent along x, y, z, metres, all positive.
        kind: one of :data:`BOX_KINDS`; decides the textures.
    """

    centre: tuple[float, float, float]
    size: tuple[float, float, float]
    kind: str = "cabinet"

    def __post_init__(self) -> None:
        centre = np.asarray(self.centre, dtype=float).reshape(-1)
        size = np.asarray(self.size, dtype=float).reshape(-1)
        if centre.shape != (3,) or not np.all(np.isfinite(centre)):
            raise InputError(f"Box.centre: expected 3 finite numbers, got {self.centre!r}")
        if size.shape != (3,) or not np.all(size > 0) or not np.all(np.isfinite(size)):
            raise InputError(f"Box.size: expected 3 positive finite numbers, got {self.size!r}")
        if self.kind not in BOX_KINDS:
            raise InputError(f"Box.kind: expected one of {BOX_KINDS}, got {self.kind!r}")
        object.__setattr__(self, "centre", tuple(float(c) for c in centre))
        object.__setattr__(self, "size", tuple(float(s) for s in size))

    @property
    def lo(self) -> np.ndarray:
        """``(3,)`` minimum corner."""
        return np.asarray(self.centre) - 0.5 * np.asarray(self.size)

    @property
    def hi(self) -> np.ndarray:
        """``(3,)`` maximum corner."""
        return np.asarray(self.centre) + 0.5 * np.asarray(self.size)


@dataclass(frozen=True)
class Room:
    """A textured box-shaped room with furniture.

    Attributes:
        width: extent along x, metres; the room spans ``x in [-width/2, width/2]``.
        depth: extent along y, metres; ``y in [-depth/2, depth/2]``.
        height: extent along z, metres; ``z in [0, height]``.
        boxes: the objects in the room.
        seed: non-negative texture seed; the same seed gives the same textures.
    """

    width: float
    depth: float
    height: float
    boxes: tuple[Box, ...] = ()
    seed: int = 0

    def __post_init__(self) -> None:
        for name in ("width", "depth", "height"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise InputError(f"Room.{name}: must be a positive number of metres, got {value!r}")
            object.__setattr__(self, name, float(value))
        boxes = tuple(self.boxes)
        if not all(isinstance(b, Box) for b in boxes):
            raise InputError("Room.boxes: expected a sequence of Box")
        object.__setattr__(self, "boxes", boxes)
        if int(self.seed) != self.seed or self.seed < 0:
            raise InputError(f"Room.seed: expected a non-negative integer, got {self.seed!r}")
        object.__setattr__(self, "seed", int(self.seed))

    @property
    def lo(self) -> np.ndarray:
        """``(3,)`` minimum corner of the room."""
        return np.array([-self.width / 2, -self.depth / 2, 0.0])

    @property
    def hi(self) -> np.ndarray:
        """``(3,)`` maximum corner of the room."""
        return np.array([self.width / 2, self.depth / 2, self.height])

    def is_free(self, points: np.ndarray, margin: float = 0.0) -> np.ndarray:
        """``(...)`` bool: points ``(..., 3)`` are inside the room and outside every box, by ``margin`` metres.

        A negative margin accepts points on (or just past) the surfaces.
        """
        points = np.asarray(points, dtype=float)
        free = np.all((points > self.lo + margin) & (points < self.hi - margin), axis=-1)
        for box in self.boxes:
            free &= ~np.all((points > box.lo - margin) & (points < box.hi + margin), axis=-1)
        return free


@dataclass(frozen=True)
class Surface:
    """One textured rectangle of a room: points ``origin + s u_axis + r v_axis`` for ``s, r`` in ``extent``.

    Texture rows run along ``v_axis`` and columns along ``u_axis``; on vertical surfaces ``v_axis``
    points down and ``origin`` is the top-left corner as seen from the room, so pictures stand upright.

    Attributes:
        surface_id: index of the surface (see the module docstring).
        kind: ``"floor"``, ``"ceiling"``, ``"wall"`` or the box's kind.
        origin: ``(3,)`` corner of the rectangle, world frame.
        u_axis: ``(3,)`` unit vector along the texture columns.
        v_axis: ``(3,)`` unit vector along the texture rows.
        normal: ``(3,)`` unit normal pointing into the free space the surface is seen from.
        extent: ``(2,)`` size along ``u_axis`` and ``v_axis``, metres.
    """

    surface_id: int
    kind: str
    origin: tuple[float, float, float]
    u_axis: tuple[float, float, float]
    v_axis: tuple[float, float, float]
    normal: tuple[float, float, float]
    extent: tuple[float, float]

    @property
    def texture_shape(self) -> tuple[int, int]:
        """``(rows, cols)`` of the surface's texture at :data:`TEXEL_SIZE`."""
        return (max(4, int(np.ceil(self.extent[1] / TEXEL_SIZE))),
                max(4, int(np.ceil(self.extent[0] / TEXEL_SIZE))))


def _face_surface(surface_id: int, kind: str, lo: np.ndarray, hi: np.ndarray, axis: int,
                  high_side: bool, normal_sign: float) -> Surface:
    """The face of the box ``[lo, hi]`` on ``axis`` at its low or high side, seen from ``normal_sign * e_axis``."""
    up = np.array([0.0, 0.0, 1.0])
    normal = np.zeros(3)
    normal[axis] = normal_sign
    centre = 0.5 * (lo + hi)
    centre[axis] = hi[axis] if high_side else lo[axis]
    size = hi - lo
    # Textures read unmirrored from the free side: u (right) x v (down) = -normal, as for a viewer.
    if axis == 2:
        u, v = np.array([1.0, 0.0, 0.0]), np.array([0.0, -normal_sign, 0.0])
    else:
        u, v = np.cross(up, normal), -up  # facing -normal with z up, the right is up x normal
    extent = (float(abs(u) @ size), float(abs(v) @ size))
    origin = centre - 0.5 * extent[0] * u - 0.5 * extent[1] * v
    as_t = lambda a: tuple(float(x) for x in a)
    return Surface(surface_id, kind, as_t(origin), as_t(u), as_t(v), as_t(normal), extent)


def room_surfaces(room: Room) -> tuple[Surface, ...]:
    """All surfaces of ``room``, indexed by surface id: 6 room planes, then 6 faces per box."""
    lo, hi = room.lo, room.hi
    surfaces = [
        _face_surface(0, "floor", lo, hi, 2, False, +1.0),
        _face_surface(1, "ceiling", lo, hi, 2, True, -1.0),
        _face_surface(2, "wall", lo, hi, 0, False, +1.0),
        _face_surface(3, "wall", lo, hi, 0, True, -1.0),
        _face_surface(4, "wall", lo, hi, 1, False, +1.0),
        _face_surface(5, "wall", lo, hi, 1, True, -1.0),
    ]
    for i, box in enumerate(room.boxes):
        for axis in range(3):
            for side in (0, 1):
                sid = NUM_ROOM_SURFACES + 6 * i + 2 * axis + side
                surfaces.append(_face_surface(sid, box.kind, box.lo, box.hi, axis, bool(side),
                                              -1.0 if side == 0 else 1.0))
    return tuple(surfaces)


# ----------------------------------------------------------------------------------------------------
# Room layout


_SIZE_RANGES = {
    # kind: (along-wall length, depth, height) ranges in metres; None height = floor to ceiling.
    "cabinet": ((0.6, 1.4), (0.4, 0.6), (0.7, 1.2)),
    "shelf": ((0.8, 1.6), (0.3, 0.4), (1.6, 2.2)),
    "table": ((1.0, 1.6), (0.6, 0.8), (0.72, 0.8)),
    "panel": ((1.0, 1.8), (0.04, 0.06), (1.5, 2.0)),
    "pillar": ((0.3, 0.5), (0.3, 0.5), None),
}


def make_room(seed: int, width: float = 8.0, depth: float = 7.0, height: float = 3.0,
              num_objects: int = 6, keep_clear: tuple[float, float] = (5.0, 4.0)) -> Room:
    """A furnished room, deterministic from ``seed``.

    Cabinets, shelves and tables stand against the walls; panels (thin boxes) and pillars stand free
    between the walls and the clear centre, parallel to the walls, so views have parallax. Objects do
    not overlap and keep 0.15 m apart.

    Args:
        seed: non-negative integer; the same arguments give the same room.
        width, depth, height: room extent along x, y, z, metres.
        num_objects: how many boxes; kinds cycle through :data:`BOX_KINDS` in a seeded order.
        keep_clear: ``(x, y)`` size of the central region, centred at the origin, left free for people.
    Returns:
        the room.
    """
    if int(seed) != seed or seed < 0:
        raise InputError(f"make_room: seed must be a non-negative integer, got {seed!r}")
    if height < 2.2:
        raise InputError(f"make_room: height must be at least 2.2 m for the furniture, got {height}")
    if num_objects < 0:
        raise InputError(f"make_room: num_objects must be >= 0, got {num_objects}")
    clear = np.asarray(keep_clear, dtype=float)
    if clear.shape != (2,) or np.any(clear < 0) or clear[0] >= width or clear[1] >= depth:
        raise InputError(f"make_room: keep_clear must be (x, y) sizes inside the {width} x {depth} m room, "
                         f"got {keep_clear!r}")
    Room(width, depth, height)  # validates the dimensions
    rng = np.random.default_rng([int(seed), 0x2007])
    kinds = [BOX_KINDS[i % len(BOX_KINDS)] for i in range(num_objects)]
    order = rng.permutation(num_objects)
    # Seeded order, but a panel (the best parallax cue) always comes first when there is room for it.
    kinds = sorted((kinds[i] for i in order), key=lambda k: k != "panel")
    room_half = np.array([width, depth]) / 2
    clear_half = clear / 2
    footprints: list[tuple[np.ndarray, np.ndarray]] = []
    boxes = []
    for kind in kinds:
        for _ in range(500):
            box = _sample_box(rng, kind, room_half, clear_half, height)
            lo, hi = np.asarray(box.lo[:2]), np.asarray(box.hi[:2])
            inside = np.all(lo >= -room_half) and np.all(hi <= room_half)
            in_clear = np.all(lo < clear_half) and np.all(hi > -clear_half)
            overlaps = any(np.all(lo < o_hi + 0.15) and np.all(hi > o_lo - 0.15) for o_lo, o_hi in footprints)
            if inside and not in_clear and not overlaps:
                footprints.append((lo, hi))
                boxes.append(box)
                break
        else:
            raise InputError(f"make_room: could not fit {num_objects} objects around a {clear[0]} x {clear[1]} m "
                             f"clear centre in a {width} x {depth} m room; use fewer objects or a smaller keep_clear")
    return Room(width, depth, height, tuple(boxes), int(seed))


def _sample_box(rng: np.random.Generator, kind: str, room_half: np.ndarray, clear_half: np.ndarray,
                height: float) -> Box:
    """One random placement of a ``kind`` box near a random wall (not yet checked for collisions)."""
    along_range, depth_range, height_range = _SIZE_RANGES[kind]
    along = rng.uniform(*along_range)
    thick = rng.uniform(*depth_range)
    tall = height if height_range is None else rng.uniform(height_range[0], min(height_range[1], height - 0.2))
    axis = int(rng.integers(2))  # the wall's normal axis: 0 -> walls at x = +-w/2, 1 -> y = +-d/2
    sign = rng.choice([-1.0, 1.0])
    other = 1 - axis
    ring = room_half[axis] - clear_half[axis]  # free band between the wall and the clear centre
    if kind in ("panel", "pillar"):
        # Free-standing: at least 0.3 m from the wall so it casts parallax against it.
        offset = rng.uniform(0.3, max(0.3, ring - thick)) + thick / 2
    else:
        offset = rng.uniform(0.03, 0.08) + thick / 2
    centre = np.zeros(3)
    size = np.zeros(3)
    centre[axis] = sign * (room_half[axis] - offset)
    centre[other] = rng.uniform(-room_half[other] + along / 2 + 0.05, room_half[other] - along / 2 - 0.05)
    size[axis], size[other] = thick, along
    size[2] = tall
    centre[2] = tall / 2
    return Box(tuple(centre), tuple(size), kind)


# ----------------------------------------------------------------------------------------------------
# Textures


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
