import numpy as np
import pytest

from multithumbs.synth.room import Room, make_room, room_surfaces
from multithumbs.synth.textures import surface_texture, texture_atlas


@pytest.fixture(scope="module")
def room() -> Room:
    return make_room(0)


def test_textures_are_deterministic_and_depend_on_seed(room):
    surfaces = room_surfaces(room)
    wall = surfaces[2]
    tex = surface_texture(room.seed, wall)
    assert tex.dtype == np.uint8 and tex.shape == (*wall.texture_shape, 3)
    assert not tex.flags.writeable  # cached: callers must not change it
    again = surface_texture.__wrapped__(room.seed, wall)
    np.testing.assert_array_equal(tex, again)
    other = surface_texture(room.seed + 1, wall)
    assert np.abs(tex.astype(int) - other.astype(int)).mean() > 10
    # Surfaces of one room differ from each other too (no repeated textures).
    assert np.abs(tex.astype(int) - surface_texture(room.seed, surfaces[3])[:, :tex.shape[1]].astype(int)
                  [:tex.shape[0]]).mean() > 10


def test_textures_have_fine_detail_and_floor_differs_from_walls(room):
    surfaces = room_surfaces(room)
    floor = surface_texture(room.seed, surfaces[0]).astype(float)
    walls = [surface_texture(room.seed, s).astype(float) for s in surfaces[2:6]]
    # Texel-scale detail: neighbouring texels differ (no large flat areas).
    for tex in [floor, *walls]:
        grey = tex.mean(axis=2)
        assert np.abs(np.diff(grey, axis=1)).mean() > 1.0
    # The floor does not look like the walls: their mean colours differ.
    assert np.abs(floor.reshape(-1, 3).mean(0) - np.concatenate([w.reshape(-1, 3) for w in walls]).mean(0)).max() > 15


def test_atlas_holds_every_texture(room):
    atlas = texture_atlas(room)
    for s in room_surfaces(room):
        x, y = atlas.offsets[s.surface_id]
        rows, cols = atlas.shapes[s.surface_id]
        np.testing.assert_array_equal(atlas.image[y:y + rows, x:x + cols], surface_texture(room.seed, s))
    assert texture_atlas(room) is atlas  # cached per room
