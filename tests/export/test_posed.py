import numpy as np
import pytest

from multithumbs.errors import InputError
from multithumbs.export.posed import (
    camera_centres, posed_joints, posed_people, rotation_to_y_up, rotation_to_z_up, shot_index, world_up,
)
from tests.export.conftest import rigid_copy, tilted_rotation


def test_posed_people_shapes_and_values(small_scene, body):
    world = small_scene.world
    vertices, joints = posed_people(world, body, people=[1], frames=[0, 7], chunk=1)
    assert vertices.shape == (1, 2, body.num_vertices, 3) and vertices.dtype == np.float32
    assert joints.shape == (1, 2, 24, 3)
    np.testing.assert_allclose(vertices[0], small_scene.video.vertices[1, [0, 7]], atol=1e-4)
    np.testing.assert_allclose(posed_joints(world, body)[1, [0, 7]], joints[0], atol=1e-4)


def test_world_up_of_truth_is_z(small_scene, body):
    np.testing.assert_array_equal(world_up(small_scene.world, posed_joints(small_scene.world, body)), [0, 0, 1])
    np.testing.assert_array_equal(world_up(small_scene.world), [0, 0, 1])  # from the cameras alone


def test_world_up_follows_a_tilted_world(small_scene, body):
    rotation = tilted_rotation()
    moved = rigid_copy(small_scene.world, body, rotation, np.array([1.0, 2.0, 3.0]))
    up = world_up(moved, posed_joints(moved, body))
    assert np.degrees(np.arccos(np.clip(up @ rotation[:, 2], -1, 1))) < 8.0


@pytest.mark.parametrize("seed", range(5))
def test_up_rotations(seed):
    up = np.random.default_rng(seed).normal(size=3)
    up /= np.linalg.norm(up)
    for rot, axis in ((rotation_to_y_up(up), [0, 1, 0]), (rotation_to_z_up(up), [0, 0, 1])):
        np.testing.assert_allclose(rot @ rot.T, np.eye(3), atol=1e-12)
        assert np.linalg.det(rot) == pytest.approx(1.0)
        np.testing.assert_allclose(rot @ up, axis, atol=1e-12)
    np.testing.assert_allclose(rotation_to_y_up([0, 0, 1]) @ [1, 2, 3], [1, 3, -2], atol=1e-12)
    np.testing.assert_allclose(rotation_to_z_up([0, 0, 1]), np.eye(3), atol=1e-12)
    np.testing.assert_allclose(rotation_to_y_up([0, -1, 0]) @ [0, -1, 0], [0, 1, 0], atol=1e-12)


def test_cameras_and_shots(small_scene):
    world = small_scene.world
    centres = camera_centres(world)
    np.testing.assert_allclose(np.einsum("tij,tj->ti", world.R, centres) + world.t, 0, atol=1e-9)
    shots = shot_index(world)
    cut = int(world.cut_frames[0])
    assert shots[cut - 1] == 0 and shots[cut] == 1


def test_world_up_without_people_or_consistent_cameras(small_scene):
    import dataclasses

    world = small_scene.world
    t = world.num_frames
    # Half the frames upright, half upside down, all looking the same way: no up direction to tell.
    R = np.where((np.arange(t) < t // 2)[:, None, None], np.eye(3), np.diag([-1.0, -1.0, 1.0]))
    confused = dataclasses.replace(world, valid=np.zeros_like(world.valid), R=R)
    with pytest.raises(InputError, match="up direction"):
        world_up(confused)
