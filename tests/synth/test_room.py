import dataclasses

import numpy as np
import pytest

from multithumbs.errors import InputError
from multithumbs.synth.room import BOX_KINDS, NUM_ROOM_SURFACES, Box, Room, make_room, room_surfaces


@pytest.fixture(scope="module")
def room() -> Room:
    return make_room(0)


def test_make_room_is_deterministic_and_seeded():
    assert make_room(5) == make_room(5)
    assert make_room(5).boxes != make_room(6).boxes


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_boxes_stand_on_the_floor_near_walls_and_leave_the_centre_clear(seed):
    keep_clear = (5.0, 4.0)
    room = make_room(seed, keep_clear=keep_clear)
    assert len(room.boxes) == 6
    assert {b.kind for b in room.boxes} == set(BOX_KINDS)
    half_clear = np.array(keep_clear) / 2
    for i, box in enumerate(room.boxes):
        assert box.lo[2] == pytest.approx(0.0) and box.hi[2] <= room.height + 1e-9
        assert np.all(box.lo >= room.lo) and np.all(box.hi <= room.hi)
        # The footprint misses the central rectangle.
        assert np.any(box.lo[:2] >= half_clear) or np.any(box.hi[:2] <= -half_clear)
        for other in room.boxes[i + 1:]:
            gap = np.maximum(other.lo[:2] - box.hi[:2], box.lo[:2] - other.hi[:2])
            assert gap.max() >= 0.15 - 1e-9
    # Free-standing panels keep away from the walls (parallax against them).
    for panel in (b for b in room.boxes if b.kind == "panel"):
        thin = int(np.argmin(panel.size[:2]))
        assert min(panel.lo[thin] - room.lo[thin], room.hi[thin] - panel.hi[thin]) >= 0.3 - 1e-9


def test_is_free(room):
    box = room.boxes[0]
    assert room.is_free(np.array([0.0, 0.0, 1.0]))
    assert not room.is_free(box.centre)
    assert not room.is_free(np.array([0.0, 0.0, -0.1]))
    assert room.is_free(np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 5.0]])).tolist() == [True, False]


def test_surfaces_tile_the_room_and_box_faces(room):
    surfaces = room_surfaces(room)
    assert len(surfaces) == NUM_ROOM_SURFACES + 6 * len(room.boxes)
    for sid, s in enumerate(surfaces):
        assert s.surface_id == sid
        origin, u, v, n = (np.array(a) for a in (s.origin, s.u_axis, s.v_axis, s.normal))
        # Texture axes read unmirrored from the free side, like an image: right x down = into the surface.
        np.testing.assert_allclose(np.cross(u, v), -n, atol=1e-12)
        centre = origin + 0.5 * s.extent[0] * u + 0.5 * s.extent[1] * v
        corners = [origin + a * s.extent[0] * u + b * s.extent[1] * v for a in (0, 1) for b in (0, 1)]
        if sid < NUM_ROOM_SURFACES:
            lo, hi = room.lo, room.hi
            assert np.all(centre + 0.01 * n > lo) and np.all(centre + 0.01 * n < hi)  # normal points inside
        else:
            box = room.boxes[(sid - NUM_ROOM_SURFACES) // 6]
            lo, hi = box.lo, box.hi
            inner = centre - 0.01 * n
            assert np.all(inner > lo) and np.all(inner < hi)  # normal points out of the box
        for corner in corners:
            assert np.all(corner >= lo - 1e-9) and np.all(corner <= hi + 1e-9)
        # The rectangle spans a whole face: its corners are corners of the box.
        spans = np.ptp(np.array(corners), axis=0)
        np.testing.assert_allclose(np.sort(spans)[1:], np.sort(np.delete(hi - lo, np.argmax(np.abs(n)))), atol=1e-9)


def test_invalid_inputs_raise_input_error():
    with pytest.raises(InputError, match="seed"):
        make_room(-1)
    with pytest.raises(InputError, match="keep_clear"):
        make_room(0, keep_clear=(9.0, 4.0))
    with pytest.raises(InputError, match="could not fit"):
        make_room(0, num_objects=60)
    with pytest.raises(InputError, match="Box.size"):
        Box((0, 0, 0), (1, -1, 1))
    with pytest.raises(InputError, match="Box.kind"):
        Box((0, 0, 0), (1, 1, 1), "sofa")
    with pytest.raises(InputError, match="Room.width"):
        Room(-1.0, 7.0, 3.0)
    with pytest.raises(InputError, match="Room.seed"):
        dataclasses.replace(make_room(0, num_objects=0), seed=-3)
