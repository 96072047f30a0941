"""Procedural textured rooms for the synthetic benchmark: their geometry (textures: :mod:`multithumbs.synth.textures`).

World frame: metric, +z up, floor at ``z = 0`` (:mod:`multithumbs.conventions`). A room spans
``x in [-w/2, w/2]``, ``y in [-d/2, d/2]``, ``z in [0, h]`` and holds axis-aligned :class:`Box` es
(furniture, shelves, free-standing panels, pillars) near its walls, leaving the centre free for people.

Every flat face is a :class:`Surface` with an id:
``0`` floor, ``1`` ceiling, ``2..5`` the walls at ``x = -w/2, x = +w/2, y = -d/2, y = +d/2``, then six
per box, ``6 + 6 i + 2 a + s`` for the face of box ``i`` on axis ``a`` (0 x, 1 y, 2 z) at its low
(``s = 0``) or high (``s = 1``) side. Each surface gets a texture from ``(room seed, surface)``
(:func:`multithumbs.synth.textures.surface_texture`).
"""

from __future__ import annotations

from dataclasses import dataclass

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
