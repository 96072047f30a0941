import numpy as np
import pytest

from multithumbs.errors import InputError
from multithumbs.export.posed import posed_joints
from multithumbs.export.smpl import person_file_name, smpl_arrays, write_smpl_npz


def test_npz_fields_round_trip(small_scene, body, tmp_path):
    world = small_scene.world
    joints = posed_joints(world, body)
    path = write_smpl_npz(tmp_path / person_file_name(world.person_ids[1], ".npz"), world, 1, joints[1],
                          np.array([0.0, 0.0, 1.0]), body.source)
    assert path.name == "person_01.npz"
    with np.load(path, allow_pickle=False) as data:
        t = world.num_frames
        assert int(data["person_id"]) == int(world.person_ids[1])
        np.testing.assert_array_equal(data["frames"], np.arange(t))
        np.testing.assert_array_equal(data["valid"], world.valid[1])
        np.testing.assert_allclose(data["global_orient"], world.global_orient[1])
        np.testing.assert_allclose(data["body_pose"], world.body_pose[1])
        np.testing.assert_allclose(data["betas"], world.betas[1])
        np.testing.assert_allclose(data["transl"], world.transl[1])
        np.testing.assert_allclose(data["joints"], joints[1])
        assert data["poses"].shape == (t, 72)
        np.testing.assert_allclose(data["poses"][:, 3:].reshape(t, 23, 3), world.body_pose[1])
        np.testing.assert_allclose(data["trans"], world.transl[1])
        assert float(data["mocap_framerate"]) == world.fps == float(data["fps"])
        assert str(data["gender"]) == "neutral" and str(data["body_model"]) == body.source
        np.testing.assert_array_equal(data["cut_frames"], world.cut_frames)
        assert data["shot"][-1] == world.cut_frames.size
        assert {tuple(r) for r in data["track_ids"]} == {(0, 1), (1, 1)}


def test_joints_reproduce_from_parameters(small_scene, body):
    """The saved parameters pose to the saved joints with smplx's forward pass."""
    world = small_scene.world
    joints = posed_joints(world, body)
    arrays = smpl_arrays(world, 0, joints[0], np.array([0, 0, 1.0]))
    out = body.forward(arrays["global_orient"], arrays["body_pose"], arrays["betas"], arrays["transl"])
    np.testing.assert_allclose(out.joints.detach().numpy(), arrays["joints"], atol=1e-4)


def test_bad_person(small_scene):
    with pytest.raises(InputError, match="out of range"):
        smpl_arrays(small_scene.world, 5, np.zeros((12, 24, 3)), np.array([0, 0, 1.0]))
