import hashlib
from dataclasses import replace

import numpy as np
import pytest
import trimesh
from scipy.spatial import cKDTree

from multithumbs.body import procedural
from multithumbs.body.procedural import (
    BETA_DIRECTIONS, NEUTRAL_JOINTS, PROCEDURAL_MODEL_VERSION, SOLE_HEIGHT, Proportions, body_vertices,
    build_procedural_smpl, procedural_model_path, write_procedural_smpl,
)
from multithumbs.conventions import NUM_BETAS, SMPL_PARENTS


@pytest.fixture(scope="module")
def body():
    return build_procedural_smpl()


def shaped(body, k, value):
    return body["v_template"] + value * body["shapedirs"][:, :, k]


def height(vertices):
    return vertices[:, 1].max() - vertices[:, 1].min()


def tree_distance(a, b):
    chain = lambda j: [j] + (chain(SMPL_PARENTS[j]) if SMPL_PARENTS[j] >= 0 else [])  # noqa: E731
    ca, cb = chain(a), chain(b)
    common = next(j for j in ca if j in cb)
    return ca.index(common) + cb.index(common)


def sha256(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_file_is_byte_identical_every_time(tmp_path, body):
    first = write_procedural_smpl(tmp_path / "a.npz")
    second = write_procedural_smpl(tmp_path / "b.npz")
    assert sha256(first) == sha256(second)
    with np.load(first) as npz:
        assert sorted(npz.files) == sorted(body)
        for key in body:
            np.testing.assert_array_equal(npz[key], body[key])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.npz", "b.npz"]  # no temporary left behind


def test_arrays_have_the_shapes_smplx_reads(body):
    n = len(body["v_template"])
    assert 2500 <= n <= 4000
    assert body["shapedirs"].shape == (n, 3, NUM_BETAS)
    assert body["posedirs"].shape == (n, 3, 207) and not body["posedirs"].any()
    assert body["J_regressor"].shape == (24, n)
    assert body["weights"].shape == (n, 24)
    assert body["part_labels"].shape == (n,) and body["part_labels"].dtype.kind == "i"
    assert body["f"].dtype == np.int64 and body["f"].min() == 0 and body["f"].max() == n - 1
    np.testing.assert_array_equal(body["kintree_table"][0], SMPL_PARENTS)
    np.testing.assert_array_equal(body["kintree_table"][1], np.arange(24))


def test_mesh_is_closed_and_wound_outwards(body):
    faces = body["f"]
    directed = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    _, counts = np.unique(np.sort(directed, axis=1), axis=0, return_counts=True)
    assert np.all(counts == 2)  # every edge shared by exactly two faces
    assert len(np.unique(directed, axis=0)) == len(directed)  # ... traversed once each way: consistent winding
    mesh = trimesh.Trimesh(body["v_template"], faces, process=False)
    parts = mesh.split(only_watertight=False)
    assert len(parts) == 9  # torso, neck, head, 2 legs, 2 feet, 2 arms
    assert all(part.is_watertight and part.volume > 0 for part in parts)
    assert 0.05 < mesh.volume < 0.09  # m^3: a 60-90 kg person (overlaps at joints counted twice)


def test_skinning_weights_are_convex_and_blend_across_joints(body):
    w = body["weights"]
    assert w.min() >= 0
    np.testing.assert_allclose(w.sum(axis=1), 1.0, atol=1e-8)
    # The part label is the joint owning the vertex, and it carries most of the weight.
    assert np.mean(w[np.arange(len(w)), body["part_labels"]] >= 0.5) > 0.95
    for parent, child in ((1, 4), (4, 7), (16, 18), (18, 20), (3, 6), (12, 15)):
        mixed = (w[:, parent] > 0.2) & (w[:, child] > 0.2)
        assert mixed.sum() >= 8, (parent, child)  # a smooth seam, not a cut
    # Skinning follows the kinematic tree: a vertex only mixes joints close to its own in the tree.
    for vertex_weights, label in zip(w, body["part_labels"]):
        for joint in np.flatnonzero(vertex_weights):
            assert tree_distance(joint, label) <= 2, (joint, label)


def test_joint_regressor_reproduces_rest_joints(body):
    regressor = body["J_regressor"]
    assert regressor.min() >= 0
    np.testing.assert_allclose(regressor.sum(axis=1), 1.0, atol=1e-8)
    np.testing.assert_allclose(regressor @ body["v_template"], body["joint_rest"], atol=1e-6)
    np.testing.assert_allclose(body["joint_rest"], NEUTRAL_JOINTS, atol=1e-9)


def test_body_frame_and_proportions(body):
    v, joints = body["v_template"], body["joint_rest"]
    assert 1.6 <= height(v) <= 1.8
    np.testing.assert_allclose(joints[0], 0.0, atol=1e-9)  # pelvis at the origin
    assert abs(v[:, 1].min() - SOLE_HEIGHT) < 0.005 and abs(v[:, 1].max() - 0.75) < 0.005
    assert joints[1, 0] > 0 > joints[2, 0]  # the body's left is +x
    assert joints[16, 0] > 0.1 and joints[22, 0] > 0.7  # T-pose: left arm along +x
    feet = np.isin(body["part_labels"], [10, 11])
    assert v[feet, 2].max() > 0.15 and np.all(joints[[10, 11], 2] > joints[[7, 8], 2])  # toes forward (+z)
    head = body["part_labels"] == 15
    assert v[head, 2].max() > -v[head, 2].min() - 0.02  # the face is at the front
    # Left/right mirror symmetry.
    assert cKDTree(v).query(v * [-1, 1, 1])[0].max() < 1e-9


def test_height_beta_grows_the_body_monotonically(body):
    heights = [height(shaped(body, 0, b)) for b in np.linspace(-2, 2, 9)]
    assert np.all(np.diff(heights) > 0)
    per_unit = (heights[-1] - heights[0]) / 4
    assert 0.05 < per_unit < 0.07
    soles = [shaped(body, 0, b)[:, 1].min() for b in (-2, 2)]
    np.testing.assert_allclose(soles, body["v_template"][:, 1].min(), atol=5e-4)  # about the soles


def test_girth_beta_widens_without_changing_height(body):
    waist = np.abs(body["v_template"][:, 1] - 0.11) < 0.02
    torso = waist & (body["part_labels"] <= 6)
    widths = [np.ptp(shaped(body, 1, b)[torso, 0]) for b in np.linspace(-2, 2, 5)]
    assert np.all(np.diff(widths) > 0) and widths[-1] / widths[0] > 1.3
    assert abs(height(shaped(body, 1, 2.0)) - height(body["v_template"])) < 0.005


@pytest.mark.parametrize("k", range(NUM_BETAS))
def test_every_beta_stays_plausible(body, k):
    rest = body["v_template"]
    assert np.abs(body["shapedirs"][:, :, k]).max() > 0.004  # a direction that does something
    for b in (-2.0, 2.0):
        v = shaped(body, k, b)
        assert 1.55 < height(v) < 1.85
        assert np.abs(v - rest).max() < 0.15
        assert abs(v[:, 1].min() - rest[:, 1].min()) < 0.003  # soles stay on the floor
        assert trimesh.Trimesh(v, body["f"], process=False).volume > 0.04


def test_shape_directions_mean_what_they_say(body):
    regressor = body["J_regressor"]
    joints = lambda k, b: regressor @ shaped(body, k, b)  # noqa: E731
    shin = lambda j: np.linalg.norm(j[7] - j[4])  # noqa: E731
    arm = lambda j: np.linalg.norm(j[20] - j[16])  # noqa: E731
    assert shin(joints(2, 1)) > shin(joints(2, -1)) + 0.03  # leg length
    assert arm(joints(3, 1)) > arm(joints(3, -1)) + 0.03  # arm length
    assert joints(4, 1)[16, 0] > joints(4, -1)[16, 0] + 0.01  # shoulder width
    assert joints(5, 1)[1, 0] > joints(5, -1)[1, 0] + 0.01  # hip width
    head = body["part_labels"] == 15
    assert np.ptp(shaped(body, 6, 1)[head, 1]) > np.ptp(shaped(body, 6, -1)[head, 1]) + 0.015  # head size
    v, belly_dir = body["v_template"], body["shapedirs"][:, :, 7]
    abdomen = (np.abs(v[:, 1] - 0.09) < 0.02) & (np.abs(v[:, 0]) < 0.03) & (body["part_labels"] <= 3)
    front, back = abdomen & (v[:, 2] > 0), abdomen & (v[:, 2] < 0)
    assert belly_dir[front, 2].min() > 0.01 and np.abs(belly_dir[back, 2]).max() < 0.002  # belly: front only
    assert np.linalg.norm(joints(8, 1)[12] - joints(8, 1)[0]) > np.linalg.norm(joints(8, -1)[12] - joints(8, -1)[0]) + 0.03


def test_shapedirs_follow_the_generator(body):
    # One unit of a beta is one step of its proportion: the linear model matches the generated body.
    for k, (name, step) in enumerate(BETA_DIRECTIONS):
        mean = Proportions()
        vertices, joints = body_vertices(replace(mean, **{name: getattr(mean, name) + step}))
        assert np.abs(shaped(body, k, 1.0) - vertices).max() < 0.005, name
        # Joints move with the surface around them: the belly carries the lower spine along a little.
        np.testing.assert_allclose(body["J_regressor"] @ vertices, joints, atol=0.01 if name == "belly" else 0.002)


def test_model_path_is_cached_by_version(tmp_path, monkeypatch):
    monkeypatch.setenv("MULTITHUMBS_CACHE", str(tmp_path / "cache"))
    path = procedural_model_path()
    assert path.parent == tmp_path / "cache" and PROCEDURAL_MODEL_VERSION in path.name and path.is_file()
    stamp = path.stat().st_mtime_ns
    assert procedural_model_path() == path and path.stat().st_mtime_ns == stamp  # generated once


def test_default_cache_dir_is_under_home(monkeypatch, tmp_path):
    monkeypatch.delenv("MULTITHUMBS_CACHE", raising=False)
    monkeypatch.setenv("HOME", str(tmp_path))
    assert procedural.cache_dir() == tmp_path / ".cache" / "multithumbs"


# Checksums of version "1". Cached files are named by version: if the generator changes, bump
# PROCEDURAL_MODEL_VERSION and update these numbers, or users keep a stale cached body.
FINGERPRINT = {"1": {
    "v_template": (2742.820187, 44.948516),
    "shapedirs": (355.632147, 824.608365),
    "weights": (3802.0, 11399.63818),
    "J_regressor": (24.0, 72.1875),
}}


def test_arrays_match_their_version(body):
    for key, expected in FINGERPRINT[PROCEDURAL_MODEL_VERSION].items():
        a = body[key]
        checks = (np.abs(a).sum(), (a * (np.arange(a.size).reshape(a.shape) % 7)).sum())
        np.testing.assert_allclose(checks, expected, atol=1e-3, err_msg=f"{key}: bump PROCEDURAL_MODEL_VERSION")
