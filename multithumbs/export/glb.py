"""The whole sequence as one animated binary glTF (``.glb``), written with ``pygltflib``.

Layout (glTF 2.0, +y up, metres):

- node ``world``: rotates the reconstruction's world so that its estimated up direction is glTF's +y
  (:func:`multithumbs.export.posed.rotation_to_y_up`); everything below is in world coordinates.
- node ``person_<id>`` per person: one mesh whose base shape is the person's first exported frame and
  which has one **morph target per exported frame** (the vertex offsets to that frame's posed mesh). The
  animation sets that frame's target weight to 1 and the others to 0 (``STEP`` interpolation, keyframe
  time = frame / fps), so the vertices are exactly the body model's at every frame, pose correctives
  included. Frames where the person is not valid scale the node to 0 (hidden). Material colour = the
  global id's colour (:mod:`multithumbs.viz.palette`).
- node ``camera``: a perspective camera (vertical field of view from the first frame's ``fy``) whose
  translation and rotation follow every frame (``STEP``, so cuts are jumps), with a child ``camera_marker``
  pyramid so viewers that do not draw cameras still show it. glTF cameras look down -z with +y up: the
  node rotation is ``R^T diag(1, -1, -1)`` of the OpenCV world-to-camera ``R``.
- node ``scene_points_cut_<k>`` per cut when scene points are given: a ``POINTS`` primitive in the world.

Morph targets were chosen over per-frame meshes with visibility: one node per person keeps the scene
graph small and exact. The file grows with ``frames x vertices``; pass ``stride`` > 1 to export every
n-th frame of long videos (the weight table also grows with the square of the exported frames).
"""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np
from scipy.spatial.transform import Rotation

from multithumbs.errors import InputError
from multithumbs.export.cameras import check_scene_points
from multithumbs.export.files import atomic_output
from multithumbs.export.posed import camera_centres
from multithumbs.types import WorldResult
from multithumbs.viz.palette import id_color

_FLOAT, _UINT32 = 5126, 5125  # glTF component types
_ARRAY_BUFFER, _ELEMENT_ARRAY_BUFFER = 34962, 34963

CAMERA_MARKER_SIZE = 0.25
"""Depth (metres) of the pyramid that marks the camera."""


class _Blob:
    """The binary chunk being built, and the accessors that index it."""

    def __init__(self, gltf):
        self.gltf = gltf
        self.data = bytearray()

    def add(self, array: np.ndarray, kind: str, target: int | None = None, with_bounds: bool = False) -> int:
        import pygltflib

        arr = np.ascontiguousarray(array, dtype=np.uint32 if kind == "INDEX" else np.float32)
        pad = -len(self.data) % 4
        self.data.extend(b"\0" * pad)
        offset = len(self.data)
        self.data.extend(arr.tobytes())
        self.gltf.bufferViews.append(pygltflib.BufferView(buffer=0, byteOffset=offset, byteLength=arr.nbytes,
                                                          target=target))
        accessor_type = {"INDEX": "SCALAR", "SCALAR": "SCALAR", "VEC3": "VEC3", "VEC4": "VEC4"}[kind]
        width = {"SCALAR": 1, "VEC3": 3, "VEC4": 4}[accessor_type]
        flat = arr.reshape(-1, width)
        bounds = {}
        if with_bounds and flat.size:
            bounds = {"min": flat.min(axis=0).astype(float).tolist(), "max": flat.max(axis=0).astype(float).tolist()}
        self.gltf.accessors.append(pygltflib.Accessor(
            bufferView=len(self.gltf.bufferViews) - 1, componentType=_UINT32 if kind == "INDEX" else _FLOAT,
            count=len(flat), type=accessor_type, **bounds))
        return len(self.gltf.accessors) - 1


def _quat_xyzw(matrices: np.ndarray) -> np.ndarray:
    return Rotation.from_matrix(np.asarray(matrices, np.float64)).as_quat()


def write_glb(path: str | Path, result: WorldResult, vertices: np.ndarray, faces: np.ndarray,
              to_y_up: np.ndarray, scene_points: Sequence[np.ndarray] | None = None, stride: int = 1) -> Path:
    """Write the animated scene (module docstring) to ``path`` atomically.

    Args:
        path: output ``.glb``.
        result: the reconstruction.
        vertices: ``(P, T, V, 3)`` posed world vertices of every person (:func:`multithumbs.export.posed.posed_people`).
        faces: ``(F, 3)`` mesh faces.
        to_y_up: ``(3, 3)`` rotation from the world to glTF's +y-up frame.
        scene_points: optional world-frame points, one ``(N, 3)`` array per cut.
        stride: export every ``stride``-th frame (1 = all).
    """
    import pygltflib

    if stride < 1:
        raise InputError(f"stride: must be at least 1, got {stride}")
    p_count, t_count = result.valid.shape
    if np.shape(vertices)[:2] != (p_count, t_count):
        raise InputError(f"vertices: expected (P, T, V, 3) with P, T = {p_count}, {t_count}, got {np.shape(vertices)}")
    points = check_scene_points(scene_points, int(result.cut_frames.size))
    frames = np.arange(0, t_count, stride)
    times = (frames / result.fps).astype(np.float32)
    gltf = pygltflib.GLTF2(asset=pygltflib.Asset(generator="multithumbs", version="2.0"))
    gltf.scene = 0
    blob = _Blob(gltf)
    world = pygltflib.Node(name="world", rotation=_quat_xyzw(to_y_up).tolist(), children=[])
    gltf.nodes.append(world)
    time_acc = blob.add(times, "SCALAR", with_bounds=True)
    animation = pygltflib.Animation(name="sequence", samplers=[], channels=[])
    index_acc = blob.add(np.asarray(faces).reshape(-1), "INDEX", _ELEMENT_ARRAY_BUFFER)

    def animate(node: int, prop: str, values: np.ndarray, kind: str) -> None:
        out = blob.add(values, kind)
        animation.samplers.append(pygltflib.AnimationSampler(input=time_acc, output=out, interpolation="STEP"))
        animation.channels.append(pygltflib.AnimationChannel(
            sampler=len(animation.samplers) - 1, target=pygltflib.AnimationChannelTarget(node=node, path=prop)))

    for p in range(p_count):
        valid = result.valid[p, frames]
        kept = frames[valid]
        if kept.size == 0:
            continue  # never valid in an exported frame: nothing to show
        gid = int(result.person_ids[p])
        base = np.asarray(vertices[p, kept[0]], np.float32)
        material = pygltflib.Material(name=f"person_{gid}", doubleSided=True,
                                      pbrMetallicRoughness=pygltflib.PbrMetallicRoughness(
                                          baseColorFactor=[*id_color(gid).tolist(), 1.0], metallicFactor=0.0,
                                          roughnessFactor=0.8))
        gltf.materials.append(material)
        targets = [pygltflib.Attributes(POSITION=blob.add(np.asarray(vertices[p, f], np.float32) - base, "VEC3",
                                                          _ARRAY_BUFFER, with_bounds=True)) for f in kept]
        primitive = pygltflib.Primitive(attributes=pygltflib.Attributes(
            POSITION=blob.add(base, "VEC3", _ARRAY_BUFFER, with_bounds=True)), indices=index_acc,
            material=len(gltf.materials) - 1, targets=targets)
        gltf.meshes.append(pygltflib.Mesh(name=f"person_{gid}", primitives=[primitive], weights=[0.0] * len(kept)))
        gltf.nodes.append(pygltflib.Node(name=f"person_{gid}", mesh=len(gltf.meshes) - 1,
                                         extras={"person_id": gid, "frames": kept.tolist()}))
        node = len(gltf.nodes) - 1
        world.children.append(node)
        # One-hot weights: exported frame i shows target (number of valid frames before it); invalid frames
        # keep the last target but are hidden by the scale channel.
        target_of = np.clip(np.cumsum(valid) - 1, 0, None)
        weights = np.zeros((len(frames), len(kept)), np.float32)
        weights[np.arange(len(frames)), target_of] = 1.0
        animate(node, "weights", weights.reshape(-1), "SCALAR")
        animate(node, "scale", np.where(valid[:, None], 1.0, 0.0) * np.ones((1, 3)), "VEC3")

    # The camera: perspective, animated per frame, with a visible marker.
    h, w = result.image_size
    fy = float(result.K[0, 1, 1])
    gltf.cameras.append(pygltflib.Camera(type="perspective", name="camera", perspective=pygltflib.Perspective(
        yfov=float(2 * np.arctan(0.5 * h / fy)), aspectRatio=float(w / h), znear=0.05, zfar=1000.0)))
    d = CAMERA_MARKER_SIZE
    half_w, half_h = 0.5 * w / float(result.K[0, 0, 0]) * d, 0.5 * h / fy * d
    marker_v = np.array([[0, 0, 0], [-half_w, -half_h, -d], [half_w, -half_h, -d], [half_w, half_h, -d],
                         [-half_w, half_h, -d]], np.float32)
    marker_f = np.array([[0, 1, 2], [0, 2, 3], [0, 3, 4], [0, 4, 1], [1, 3, 2], [1, 4, 3]])
    gltf.materials.append(pygltflib.Material(name="camera", doubleSided=True, pbrMetallicRoughness=pygltflib.
                                             PbrMetallicRoughness(baseColorFactor=[0.1, 0.1, 0.1, 1.0],
                                                                  metallicFactor=0.0)))
    gltf.meshes.append(pygltflib.Mesh(name="camera_marker", primitives=[pygltflib.Primitive(
        attributes=pygltflib.Attributes(POSITION=blob.add(marker_v, "VEC3", _ARRAY_BUFFER, with_bounds=True)),
        indices=blob.add(marker_f.reshape(-1), "INDEX", _ELEMENT_ARRAY_BUFFER),
        material=len(gltf.materials) - 1)]))
    gltf.nodes.append(pygltflib.Node(name="camera_marker", mesh=len(gltf.meshes) - 1))
    marker_node = len(gltf.nodes) - 1
    cam_rot = np.swapaxes(result.R, 1, 2) @ np.diag([1.0, -1.0, -1.0])  # OpenCV camera -> glTF camera axes
    centres = camera_centres(result)
    gltf.nodes.append(pygltflib.Node(name="camera", camera=0, children=[marker_node],
                                     translation=centres[0].tolist(), rotation=_quat_xyzw(cam_rot[0]).tolist()))
    cam_node = len(gltf.nodes) - 1
    world.children.append(cam_node)
    animate(cam_node, "translation", centres[frames], "VEC3")
    animate(cam_node, "rotation", _quat_xyzw(cam_rot[frames]), "VEC4")

    for k, pts in enumerate(points):
        if not len(pts):
            continue
        gltf.meshes.append(pygltflib.Mesh(name=f"scene_points_cut_{k}", primitives=[pygltflib.Primitive(
            attributes=pygltflib.Attributes(POSITION=blob.add(pts, "VEC3", _ARRAY_BUFFER, with_bounds=True)),
            mode=pygltflib.POINTS)]))
        gltf.nodes.append(pygltflib.Node(name=f"scene_points_cut_{k}", mesh=len(gltf.meshes) - 1))
        world.children.append(len(gltf.nodes) - 1)

    gltf.animations.append(animation)
    gltf.scenes.append(pygltflib.Scene(name="multithumbs", nodes=[0]))
    gltf.buffers.append(pygltflib.Buffer(byteLength=len(blob.data)))
    gltf.set_binary_blob(bytes(blob.data))
    with atomic_output(path) as tmp:
        gltf.save_binary(str(tmp))
    return Path(path)
