import dataclasses

import numpy as np
import pygltflib
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from multithumbs.errors import InputError
from multithumbs.export.glb import write_glb
from multithumbs.export.posed import camera_centres, posed_people, rotation_to_y_up


def accessor(gltf: pygltflib.GLTF2, index: int) -> np.ndarray:
    """Decode one accessor of a loaded GLB (float32 / uint32 only, as written)."""
    acc = gltf.accessors[index]
    view = gltf.bufferViews[acc.bufferView]
    dtype = np.float32 if acc.componentType == pygltflib.FLOAT else np.uint32
    width = {"SCALAR": 1, "VEC3": 3, "VEC4": 4}[acc.type]
    data = gltf.binary_blob()[view.byteOffset + (acc.byteOffset or 0):][:acc.count * width * 4]
    return np.frombuffer(data, dtype=dtype).reshape(acc.count, width)


@pytest.fixture(scope="module")
def exported(small_scene, body, tmp_path_factory):
    world = small_scene.world
    valid = world.valid.copy()
    valid[1, 2:5] = False  # person 1 leaves for three frames
    world = dataclasses.replace(world, valid=valid)
    vertices, _ = posed_people(world, body)
    to_y = rotation_to_y_up(np.array([0, 0, 1.0]))
    points = [np.random.default_rng(0).uniform(-1, 1, (25, 3))]
    path = write_glb(tmp_path_factory.mktemp("glb") / "scene.glb", world, vertices, body.faces, to_y, points)
    return path, world, vertices, to_y


def test_trimesh_loads_the_scene(exported, body):
    path, world, vertices, to_y = exported
    scene = trimesh.load(str(path))
    assert isinstance(scene, trimesh.Scene)
    assert set(scene.geometry) == {"person_0", "person_1", "camera_marker", "scene_points_cut_0"}
    transform, name = scene.graph["person_0"]
    mesh = scene.geometry[name]
    assert len(mesh.faces) == len(body.faces)
    # The base shape is the first frame, placed by the y-up world node.
    np.testing.assert_allclose(trimesh.transform_points(mesh.vertices, transform), vertices[0, 0] @ to_y.T,
                               atol=1e-5)
    transform, name = scene.graph["scene_points_cut_0"]
    assert len(scene.geometry[name].vertices) == 25


def test_morph_target_animation_reproduces_every_frame(exported):
    path, world, vertices, _ = exported
    gltf = pygltflib.GLTF2().load(str(path))
    animation = gltf.animations[0]
    node_index = {n.name: i for i, n in enumerate(gltf.nodes)}
    channels = {(c.target.node, c.target.path): animation.samplers[c.sampler] for c in animation.channels}
    for p in range(world.num_people):
        node = node_index[f"person_{int(world.person_ids[p])}"]
        primitive = gltf.meshes[gltf.nodes[node].mesh].primitives[0]
        base = accessor(gltf, primitive.attributes.POSITION)
        targets = np.stack([accessor(gltf, t["POSITION"] if isinstance(t, dict) else t.POSITION)
                            for t in primitive.targets])
        sampler = channels[(node, "weights")]
        assert sampler.interpolation == "STEP"
        times = accessor(gltf, sampler.input)[:, 0]
        np.testing.assert_allclose(times, np.arange(world.num_frames) / world.fps, atol=1e-6)
        weights = accessor(gltf, sampler.output).reshape(world.num_frames, len(targets))
        scale = accessor(gltf, channels[(node, "scale")].output)
        for f in range(world.num_frames):
            assert scale[f, 0] == float(world.valid[p, f])
            if world.valid[p, f]:
                shown = base + np.tensordot(weights[f], targets, axes=1)
                np.testing.assert_allclose(shown, vertices[p, f], atol=1e-5)
    assert len(gltf.meshes[gltf.nodes[node_index["person_1"]].mesh].primitives[0].targets) == world.valid[1].sum()


def test_camera_animation(exported):
    path, world, _, _ = exported
    gltf = pygltflib.GLTF2().load(str(path))
    animation = gltf.animations[0]
    cam = next(i for i, n in enumerate(gltf.nodes) if n.camera is not None)
    samplers = {c.target.path: animation.samplers[c.sampler] for c in animation.channels if c.target.node == cam}
    np.testing.assert_allclose(accessor(gltf, samplers["translation"].output), camera_centres(world), atol=1e-5)
    rot = Rotation.from_quat(accessor(gltf, samplers["rotation"].output)).as_matrix()
    # glTF cameras look down -z: the node's -z axis is the OpenCV camera's viewing direction.
    np.testing.assert_allclose(-rot[:, :, 2], world.R[:, 2, :], atol=1e-5)
    perspective = gltf.cameras[0].perspective
    h, w = world.image_size
    assert perspective.aspectRatio == pytest.approx(w / h)
    assert perspective.yfov == pytest.approx(2 * np.arctan(0.5 * h / world.K[0, 1, 1]))


def test_stride_and_errors(small_scene, body, tmp_path):
    world = small_scene.world
    vertices, _ = posed_people(world, body)
    path = write_glb(tmp_path / "s.glb", world, vertices, body.faces, np.eye(3), stride=4)
    gltf = pygltflib.GLTF2().load(str(path))
    assert len(gltf.meshes[0].primitives[0].targets) == 3  # frames 0, 4, 8
    with pytest.raises(InputError, match="stride"):
        write_glb(tmp_path / "x.glb", world, vertices, body.faces, np.eye(3), stride=0)
    with pytest.raises(InputError, match="vertices"):
        write_glb(tmp_path / "x.glb", world, vertices[:, :3], body.faces, np.eye(3))
    assert not (tmp_path / "x.glb").exists()
