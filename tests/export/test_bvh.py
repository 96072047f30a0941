import bvhio
import dataclasses
import numpy as np
import pytest

from multithumbs.conventions import SMPL_JOINT_NAMES
from multithumbs.errors import InputError
from multithumbs.export.bvh import nearest_valid_frames, write_bvh
from multithumbs.export.posed import posed_joints, rotation_to_y_up, world_up
from tests.export.conftest import rigid_copy, tilted_rotation


def bvh_positions(path, frames):
    root = bvhio.readAsHierarchy(str(path))
    out = []
    for f in frames:
        root.loadPose(int(f))
        pos = {j.Name: np.array(j.PositionWorld) for j, _, _ in root.layout()}
        out.append(np.stack([pos[n] for n in SMPL_JOINT_NAMES]))
    return np.stack(out)


@pytest.mark.parametrize("tilted", [False, True])
def test_bvhio_forward_kinematics_match_smpl(small_scene, body, tmp_path, tilted):
    world = small_scene.world
    if tilted:  # a reconstructed world that is not z-up: the BVH is still y-up
        world = rigid_copy(world, body, tilted_rotation(), np.array([0.5, -1.0, 2.0]))
    joints = posed_joints(world, body)
    to_y = rotation_to_y_up(world_up(world, joints))
    path = write_bvh(tmp_path / "p.bvh", world, 1, body, joints[1], to_y)
    container = bvhio.readAsBvh(str(path))
    assert container.FrameCount == world.num_frames
    assert container.FrameTime == pytest.approx(1 / world.fps)
    frames = np.arange(world.num_frames)
    np.testing.assert_allclose(bvh_positions(path, frames), joints[1] @ to_y.T, atol=2e-5)
    # Standing people: the head is above the pelvis along BVH's +y.
    assert np.all(bvh_positions(path, [0])[0, 15, 1] > bvh_positions(path, [0])[0, 0, 1] + 0.3)


def test_scale_and_invalid_frames(small_scene, body, tmp_path):
    world = small_scene.world
    valid = world.valid.copy()
    valid[0, :4] = False
    world = dataclasses.replace(world, valid=valid)
    joints = posed_joints(world, body)
    to_y = rotation_to_y_up(np.array([0, 0, 1.0]))
    path = write_bvh(tmp_path / "p.bvh", world, 0, body, joints[0], to_y, scale=100.0)
    positions = bvh_positions(path, [0, 4])
    np.testing.assert_allclose(positions[0], positions[1], atol=1e-6)  # held at the first valid frame
    np.testing.assert_allclose(positions[1], 100.0 * joints[0, 4] @ to_y.T, atol=2e-3)


def test_nearest_valid_frames():
    np.testing.assert_array_equal(nearest_valid_frames([False, True, False, False, True, False]), [1, 1, 1, 4, 4, 4])
    np.testing.assert_array_equal(nearest_valid_frames([False, False, True]), [2, 2, 2])
    with pytest.raises(InputError, match="never valid"):
        nearest_valid_frames([False, False])
