import pickle
import sys
import types

import numpy as np
import pytest
import scipy.sparse
import smplx
import torch

from multithumbs.body import model as body_model
from multithumbs.body import smpl_files
from multithumbs.body.model import BodyModel, convert_smpl_pickle, load_body_model
from multithumbs.body.procedural import build_procedural_smpl, write_procedural_smpl
from multithumbs.conventions import SMPL_PARENTS
from multithumbs.errors import InputError
from multithumbs.geometry import axis_angle_to_matrix

LEFT_ELBOW = 18
LEFT_ELBOW_POSE = LEFT_ELBOW - 1  # body_pose excludes the pelvis


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    with pytest.MonkeyPatch.context() as mp:
        path = tmp_path_factory.mktemp("cache")
        mp.setenv("MULTITHUMBS_CACHE", str(path))
        mp.delenv(body_model.MODEL_ENV_VAR, raising=False)
        yield path


@pytest.fixture(autouse=True)
def isolated(cache, monkeypatch):
    monkeypatch.setenv("MULTITHUMBS_CACHE", str(cache))
    monkeypatch.delenv(body_model.MODEL_ENV_VAR, raising=False)


@pytest.fixture(scope="module")
def body(cache):
    return BodyModel()


@pytest.fixture(scope="module")
def arrays():
    return build_procedural_smpl()


def random_pose(generator, *batch, scale=0.6):
    return (torch.randn(*batch, 3, generator=generator) * 0.5,
            torch.randn(*batch, 23, 3, generator=generator) * scale)


def test_loads_the_procedural_body_through_smplx(body, arrays, cache):
    assert isinstance(body.smpl, smplx.SMPL)
    assert body.source == "procedural"
    assert body.num_vertices == len(arrays["v_template"]) and body.faces.dtype == np.int64
    np.testing.assert_array_equal(body.faces, arrays["f"])
    np.testing.assert_array_equal(body.parents, SMPL_PARENTS)
    np.testing.assert_array_equal(body.part_labels, arrays["weights"].argmax(axis=1))
    assert list(cache.glob("procedural_smpl_v*.npz"))
    # Foot landmarks: toes ahead of and heels behind the ankles, on the right side.
    rest = arrays["v_template"]
    l_toe, l_heel, r_toe, r_heel = rest[body.foot_vertex_ids]
    ankles = arrays["joint_rest"][[7, 8]]
    assert l_toe[2] > ankles[0, 2] + 0.1 and l_heel[2] < ankles[0, 2] - 0.03 and l_toe[0] > 0 > r_toe[0]
    assert r_toe[2] > ankles[1, 2] + 0.1 and r_heel[2] < ankles[1, 2] - 0.03
    nose = rest[body.vertex_ids["nose"]]
    assert nose[2] > arrays["joint_rest"][15, 2] + 0.08 and abs(nose[0]) < 0.01


def test_zero_pose_gives_the_rest_joints(body, arrays):
    betas = torch.randn(4, 10, generator=torch.Generator().manual_seed(0))
    out = body(torch.zeros(4, 3), torch.zeros(4, 23, 3), betas)
    torch.testing.assert_close(out.joints, body.rest_joints(betas), atol=1e-5, rtol=0)
    rest = body(np.zeros(3), np.zeros(69), np.zeros(10))
    np.testing.assert_allclose(rest.joints.numpy(), arrays["joint_rest"], atol=1e-5)
    np.testing.assert_allclose(rest.vertices.numpy(), arrays["v_template"], atol=1e-5)


def test_rotating_the_left_elbow_moves_only_the_forearm(body, arrays):
    pose = torch.zeros(23, 3)
    pose[LEFT_ELBOW_POSE] = torch.tensor([0.0, 1.2, 0.3])
    rest = body(torch.zeros(3), torch.zeros(23, 3), torch.zeros(10))
    bent = body(torch.zeros(3), pose, torch.zeros(10))
    moved_joints = (bent.joints - rest.joints).norm(dim=-1) > 1e-6
    assert moved_joints.nonzero().flatten().tolist() == [20, 22]  # left wrist and hand
    moved = ((bent.vertices - rest.vertices).norm(dim=-1) > 1e-6).numpy()
    forearm = arrays["weights"][:, [18, 20, 22]].sum(axis=1)
    assert moved.any() and not moved[forearm == 0].any()
    assert moved[forearm > 0.5].all()


def test_bone_lengths_survive_any_pose(body):
    generator = torch.Generator().manual_seed(1)
    orient, pose = random_pose(generator, 5, scale=1.0)
    betas = torch.randn(5, 10, generator=generator)
    joints = body(orient, pose, betas, torch.randn(5, 3, generator=generator)).joints
    rest = body.rest_joints(betas)
    parents = torch.tensor(SMPL_PARENTS[1:])
    bone = lambda j: (j[:, 1:] - j[:, parents]).norm(dim=-1)  # noqa: E731
    torch.testing.assert_close(bone(joints), bone(rest), atol=1e-5, rtol=0)


def test_global_orient_rotates_about_the_pelvis(body):
    generator = torch.Generator().manual_seed(2)
    _, pose = random_pose(generator)
    betas = torch.randn(10, generator=generator)
    orient = torch.tensor([0.3, -1.1, 0.5])
    upright = body(torch.zeros(3), pose, betas)
    turned = body(orient, pose, betas)
    pelvis = upright.joints[0]
    rotation = axis_angle_to_matrix(orient)
    expect = lambda x: (x - pelvis) @ rotation.T + pelvis  # noqa: E731
    torch.testing.assert_close(turned.joints, expect(upright.joints), atol=1e-5, rtol=0)
    torch.testing.assert_close(turned.vertices, expect(upright.vertices), atol=1e-5, rtol=0)


def test_transl_translates_everything(body):
    generator = torch.Generator().manual_seed(3)
    orient, pose = random_pose(generator, 2)
    betas, transl = torch.randn(2, 10, generator=generator), torch.tensor([[1.0, -2.0, 0.5], [0.0, 0.0, 3.0]])
    still = body(orient, pose, betas)
    moved = body(orient, pose, betas, transl)
    torch.testing.assert_close(moved.vertices, still.vertices + transl[:, None], atol=1e-5, rtol=0)
    torch.testing.assert_close(moved.joints, still.joints + transl[:, None], atol=1e-5, rtol=0)


def test_batches_of_any_shape_equal_per_item_results(body):
    generator = torch.Generator().manual_seed(4)
    orient, pose = random_pose(generator, 2, 3)
    transl = torch.randn(2, 3, 3, generator=generator)
    betas = torch.randn(2, 10, generator=generator)  # per person: broadcast over the 3 frames
    out = body(orient.numpy(), pose.reshape(2, 3, 69).numpy(), betas.numpy(), transl.numpy())
    assert out.vertices.shape == (2, 3, body.num_vertices, 3) and out.joints.shape == (2, 3, 24, 3)
    assert isinstance(out.vertices, torch.Tensor)
    for p in range(2):
        for t in range(3):
            one = body(orient[p, t], pose[p, t], betas[p], transl[p, t])
            torch.testing.assert_close(out.vertices[p, t], one.vertices, atol=1e-5, rtol=0)
            torch.testing.assert_close(out.joints[p, t], one.joints, atol=1e-5, rtol=0)
    shared = body(orient, pose, torch.zeros(10))  # one shape for everyone
    assert shared.joints.shape == (2, 3, 24, 3)
    empty = body(torch.zeros(0, 3), torch.zeros(0, 23, 3), torch.zeros(0, 10))
    assert empty.vertices.shape == (0, body.num_vertices, 3)


def test_chunked_calls_equal_one_call(body):
    generator = torch.Generator().manual_seed(5)
    orient, pose = random_pose(generator, 7)
    betas = torch.randn(7, 10, generator=generator)
    whole = body(orient, pose, betas)
    small = BodyModel(body_model.resolve_model_path()[0])
    small.chunk_size = 3
    parts = small(orient, pose, betas)
    torch.testing.assert_close(parts.vertices, whole.vertices)
    torch.testing.assert_close(parts.joints, whole.joints)


def test_bad_inputs_raise_input_errors(body):
    with pytest.raises(InputError, match="body_pose"):
        body(torch.zeros(3), torch.zeros(22, 3), torch.zeros(10))
    with pytest.raises(InputError, match="betas"):
        body(torch.zeros(3), torch.zeros(23, 3), torch.zeros(11))
    with pytest.raises(InputError, match="betas"):
        body(torch.zeros(4, 3), torch.zeros(4, 23, 3), torch.zeros(3, 10))
    with pytest.raises(InputError, match="broadcast"):
        body(torch.zeros(4, 3), torch.zeros(5, 23, 3), torch.zeros(10))


def test_gradients_reach_every_input():
    body = BodyModel(dtype=torch.float64)
    generator = torch.Generator().manual_seed(6)
    inputs = (torch.randn(2, 3, generator=generator, dtype=torch.float64) * 0.5,
              torch.randn(2, 23, 3, generator=generator, dtype=torch.float64) * 0.5,
              torch.randn(2, 10, generator=generator, dtype=torch.float64),
              torch.randn(2, 3, generator=generator, dtype=torch.float64))
    inputs = tuple(x.requires_grad_() for x in inputs)

    def posed(*args):
        out = body(*args)
        return out.vertices[:, ::50], out.joints  # a subsample keeps the check fast

    assert torch.autograd.gradcheck(posed, inputs, eps=1e-6, atol=1e-5, fast_mode=True)
    posed(*inputs)[0].square().sum().backward()
    assert all(x.grad is not None and x.grad.abs().sum() > 0 for x in inputs)



def test_joints_equal_the_full_forward_pass_and_its_gradients():
    # joints() walks the kinematic chain itself (for speed): it must stay SMPL's posing, values and gradients.
    body = BodyModel(dtype=torch.float64)
    generator = torch.Generator().manual_seed(11)
    orient, pose = (x.double() for x in random_pose(generator, 2, 3, scale=1.0))
    pose[0, 0] = 0.0  # zero rotations: the identity, with finite gradients
    betas = torch.randn(2, 10, generator=generator, dtype=torch.float64)
    transl = torch.randn(2, 3, 3, generator=generator, dtype=torch.float64)
    inputs = [x.clone().requires_grad_() for x in (orient, pose, betas, transl)]
    fast = body.joints(*inputs)
    full = body(*inputs).joints
    assert fast.shape == (2, 3, 24, 3)
    torch.testing.assert_close(fast, full, atol=1e-12, rtol=0)
    weights = torch.randn(fast.shape, generator=generator, dtype=torch.float64)
    for a, b in zip(torch.autograd.grad((fast * weights).sum(), inputs),
                    torch.autograd.grad((full * weights).sum(), inputs), strict=True):
        torch.testing.assert_close(a, b, atol=1e-10, rtol=1e-10)
    # The float32 model: the same joints to float32 rounding; no transl; numpy inputs.
    single = load_body_model()
    torch.testing.assert_close(single.joints(orient.numpy(), pose.numpy(), betas.numpy()),
                               single(orient, pose, betas).joints, atol=2e-6, rtol=0)


def test_rodrigues_equals_smplx_batch_rodrigues():
    from smplx.lbs import batch_rodrigues

    from multithumbs.body.model import rodrigues_coordinate_major
    generator = torch.Generator().manual_seed(12)
    rotvec = torch.randn(50, 3, generator=generator, dtype=torch.float64) * 2.0
    rotvec[:3] = 0.0
    rotvec[3:6] *= 1e-9  # near the angle offset: smplx's (slightly non-orthonormal) result is kept
    ours = rodrigues_coordinate_major(rotvec.T.reshape(3, 5, 10))
    assert ours.shape == (3, 3, 5, 10)
    torch.testing.assert_close(ours.permute(2, 3, 0, 1).reshape(50, 3, 3), batch_rodrigues(rotvec), atol=1e-14, rtol=0)


def test_kinematic_levels_pose_any_tree_order_like_smplx():
    from smplx.lbs import batch_rigid_transform, batch_rodrigues

    from multithumbs.body.model import _KinematicLevels
    # SMPL's tree (breadth-first: levels are slices) and a depth-first tree (levels need reordering).
    depth_first = np.array([-1, 0, 1, 2, 0, 4, 5, 0, 7, 8, 9, 8, 11])
    generator = torch.Generator().manual_seed(13)
    for parents in (np.asarray(SMPL_PARENTS), depth_first):
        count = len(parents)
        rotations = batch_rodrigues(torch.randn(4 * count, 3, generator=generator, dtype=torch.float64))
        rest = torch.randn(4, count, 3, generator=generator, dtype=torch.float64)
        expected, _ = batch_rigid_transform(rotations.reshape(4, count, 3, 3), rest, torch.as_tensor(parents),
                                            dtype=torch.float64)
        posed = _KinematicLevels(parents).pose(rotations.reshape(4, count, 3, 3).permute(2, 3, 1, 0),
                                               rest.permute(2, 1, 0))
        torch.testing.assert_close(posed.permute(2, 1, 0), expected, atol=1e-12, rtol=0)
    with pytest.raises(InputError, match="kinematic tree"):
        _KinematicLevels(np.array([-1, 2, 0]))


def test_a_renamed_npz_from_the_environment_loads_identically(body, arrays, tmp_path, monkeypatch):
    path = write_procedural_smpl(tmp_path / "my_body.npz")
    monkeypatch.setenv(body_model.MODEL_ENV_VAR, str(path))
    mine = BodyModel()
    assert mine.source == str(path.resolve())
    assert BodyModel(tmp_path / "my_body.npz").source == str(path.resolve())  # explicit path wins too
    generator = torch.Generator().manual_seed(7)
    orient, pose = random_pose(generator, 3)
    betas = torch.randn(3, 10, generator=generator)
    torch.testing.assert_close(mine(orient, pose, betas).vertices, body(orient, pose, betas).vertices)


def test_missing_or_broken_files_raise_input_errors(tmp_path, monkeypatch):
    with pytest.raises(InputError, match="nope.npz"):
        BodyModel(tmp_path / "nope.npz")
    monkeypatch.setenv(body_model.MODEL_ENV_VAR, str(tmp_path / "gone.pkl"))
    with pytest.raises(InputError, match="MULTITHUMBS_SMPL_MODEL.*gone.pkl"):
        BodyModel()
    broken = tmp_path / "broken.npz"
    broken.write_bytes(b"not a zip file")
    with pytest.raises(InputError, match="broken.npz"):
        BodyModel(broken)
    partial = tmp_path / "partial.npz"
    np.savez(partial, v_template=np.zeros((10, 3)))
    with pytest.raises(InputError, match="missing arrays"):
        BodyModel(partial)


def test_a_plain_pickle_is_read_by_smplx(body, arrays, tmp_path):
    path = tmp_path / "body.pkl"
    with open(path, "wb") as file:
        pickle.dump({k: arrays[k] for k in smpl_files._REQUIRED}, file)
    mine = BodyModel(path)
    assert isinstance(mine.smpl, smplx.SMPL) and mine.vertex_ids == body.vertex_ids
    generator = torch.Generator().manual_seed(8)
    orient, pose = random_pose(generator, 2)
    torch.testing.assert_close(mine(orient, pose, torch.zeros(10)).joints, body(orient, pose, torch.zeros(10)).joints)


def write_chumpy_pickle(arrays, path, monkeypatch):
    """An SMPL pickle laid out like the official files: chumpy arrays and a sparse regressor."""
    chumpy, ch = types.ModuleType("chumpy"), types.ModuleType("chumpy.ch")
    ch.Ch = type("Ch", (), {"__module__": "chumpy.ch"})
    chumpy.ch = ch
    with monkeypatch.context() as mp:
        mp.setitem(sys.modules, "chumpy", chumpy)
        mp.setitem(sys.modules, "chumpy.ch", ch)
        data = {k: arrays[k] for k in smpl_files._REQUIRED}
        for key in ("shapedirs", "v_template"):
            data[key] = ch.Ch()
            data[key].__dict__.update(x=arrays[key], _dirty_vars=set())
        data["J_regressor"] = scipy.sparse.csc_matrix(arrays["J_regressor"])
        data["kintree_table"] = arrays["kintree_table"].astype(np.uint32)
        with open(path, "wb") as file:
            pickle.dump(data, file, protocol=2)


def test_a_chumpy_pickle_gets_a_conversion_message_and_converts(body, arrays, tmp_path, monkeypatch):
    path = tmp_path / "SMPL_NEUTRAL.pkl"
    write_chumpy_pickle(arrays, path, monkeypatch)
    with pytest.raises(InputError, match="SMPL_NEUTRAL.pkl.*chumpy.*convert_smpl_pickle"):
        BodyModel(path)
    converted = BodyModel(convert_smpl_pickle(path, tmp_path / "SMPL_NEUTRAL.npz"))
    generator = torch.Generator().manual_seed(9)
    orient, pose = random_pose(generator, 2)
    betas = torch.randn(2, 10, generator=generator)
    torch.testing.assert_close(converted(orient, pose, betas).vertices, body(orient, pose, betas).vertices)


def test_load_body_model_is_cached_by_path(body, tmp_path):
    assert load_body_model() is load_body_model()
    assert load_body_model().source == "procedural"
    other = write_procedural_smpl(tmp_path / "other.npz")
    assert load_body_model(other) is load_body_model(str(other)) is not load_body_model()


_JOINT_BYTES = """
import hashlib, sys
import multithumbs, torch
from multithumbs.determinism import fix_threads
if sys.argv[1] == "pinned":
    fix_threads()
else:
    torch.set_num_threads(2)
    torch.ones(64, 64) @ torch.ones(64, 64)  # this thread's first parallel op: it keeps two threads
from multithumbs.body.model import load_body_model
body = load_body_model()
print(hashlib.sha1(body._joint_template.numpy().tobytes() + body._joint_shapedirs.numpy().tobytes()).hexdigest())
"""


def test_the_models_joint_regression_has_the_same_bytes_whatever_threads_the_process_had(cache):
    # The bench's --workers 1 loaded the model before any stage pinned torch's threads, --workers 2 after:
    # the two stored different fitted bodies under one key until the model pinned them itself.
    import os
    import subprocess

    env = {**os.environ, "MULTITHUMBS_CACHE": str(cache)}
    digests = [subprocess.run([sys.executable, "-c", _JOINT_BYTES, mode], env=env, capture_output=True, text=True,
                              check=True).stdout.strip() for mode in ("pinned", "two threads")]
    assert digests[0] and digests[0] == digests[1]
