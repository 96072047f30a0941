"""The synthetic multi-shot world (DESIGN §7): a textured room, people, cameras, and the rendered video.

``build_scene`` decides everything (room, people's motion and clothing, cameras, cuts) from a
:class:`SceneConfig` and its seed; ``synthesize`` poses the bodies, renders the spliced multi-shot
video with exact depth and instance masks, and assembles the :class:`GroundTruth`.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
import torch

from multithumbs.body.model import BodyModel
from multithumbs.geometry import camera_centre, intrinsics_from_fov, look_at, project_points, world_to_camera
# The settings and their JSON form live without torch in multithumbs.synth.config; re-exported here.
from multithumbs.synth.config import MotionConfig, SceneConfig, config_from_json, config_to_json  # noqa: F401
from multithumbs.synth.choreography import _abreast_motions, _crossing_motion, _walk_clear_of
from multithumbs.synth.clothing import Clothing, _draw_clothing
from multithumbs.synth.motion import PersonMotion, motion_to_smpl
from multithumbs.synth.render import MeshInstance, Render, render_view
from multithumbs.synth.room import Room, make_room
from multithumbs.synth.splice import even_cuts, shot_camera_ids, splice_views
from multithumbs.types import GroundTruth, WorldResult, pack_mask


@dataclass(frozen=True)
class CameraRig:
    """All cameras over all frames (before the splice).

    Attributes:
        K: ``(C, 3, 3)`` intrinsics.
        R: ``(C, T, 3, 3)`` world-to-camera rotations.
        t: ``(C, T, 3)`` world-to-camera translations.
    """

    K: np.ndarray
    R: np.ndarray
    t: np.ndarray


@dataclass(frozen=True)
class Scene:
    """Everything decided about a scene before posing and rendering.

    Attributes:
        config: the scene's config.
        room: the textured room.
        motions: one motion per person.
        presence: ``(P, T)`` bool, the person is in the room.
        betas: ``(P, 10)`` body shapes.
        clothing: one per person.
        cameras: all cameras over all frames.
        cut_frames: ``(S-1,)`` cuts.
        camera_ids: ``(T,)`` source camera of each frame.
    """

    config: SceneConfig
    room: Room
    motions: tuple[PersonMotion, ...]
    presence: np.ndarray
    betas: np.ndarray
    clothing: tuple[Clothing, ...]
    cameras: CameraRig
    cut_frames: np.ndarray
    camera_ids: np.ndarray


def _make_cameras(config: SceneConfig, rng: np.random.Generator) -> CameraRig:
    h, w = config.image_size
    K = intrinsics_from_fov(w, h, config.horizontal_fov_deg)
    t_axis = np.arange(config.num_frames) / config.fps
    base_azimuth = rng.uniform(0, 2 * np.pi)
    direction = rng.choice([-1.0, 1.0])  # cut to the left or to the right
    Rs, ts = [], []
    for k in range(config.num_shots):
        az = base_azimuth + direction * np.deg2rad(config.cut_angle_deg) * k
        height = rng.uniform(*config.camera_height)
        radial = np.array([np.cos(az), np.sin(az)])
        tangent = np.array([-radial[1], radial[0]])
        eye_xy = np.tile(config.camera_distance * radial, (config.num_frames, 1))
        target_xy = np.tile(0.3 * rng.uniform(-1, 1, 2), (config.num_frames, 1))
        if config.camera_is_moving(k):
            # Dolly sideways through the shot, centred on the shot's middle; the aim follows half-way.
            s0, s1 = np.nonzero(config_shot_mask(config, k))[0][[0, -1]]
            mid = 0.5 * (s0 + s1) / config.fps
            offset = (t_axis - mid) * config.dolly_speed * rng.choice([-1.0, 1.0])
            eye_xy = eye_xy + offset[:, None] * tangent
            target_xy = target_xy + 0.5 * offset[:, None] * tangent
        eye = np.concatenate([eye_xy, np.full((config.num_frames, 1), height)], axis=1)
        target = np.concatenate([target_xy, np.full((config.num_frames, 1), 0.9)], axis=1)
        R, t = look_at(eye, target)
        Rs.append(R)
        ts.append(t)
    return CameraRig(np.repeat(K[None], config.num_shots, 0), np.stack(Rs), np.stack(ts))


def config_shot_mask(config: SceneConfig, shot: int) -> np.ndarray:
    """``(T,)`` bool, frames of ``shot`` under the config's cuts."""
    cuts = scene_cuts(config)
    edges = [0, *cuts.tolist(), config.num_frames]
    mask = np.zeros(config.num_frames, bool)
    mask[edges[shot]:edges[shot + 1]] = True
    return mask


def scene_cuts(config: SceneConfig) -> np.ndarray:
    """The cut frames of a config (deterministic from its seed)."""
    return even_cuts(config.num_frames, config.num_shots, jitter=0.15,
                     rng=np.random.default_rng([config.seed, 1]), min_shot_length=2)


def build_scene(config: SceneConfig) -> Scene:
    """Decide room, people, motion, clothing, cameras and cuts of a scene from its config."""
    rng = np.random.default_rng([config.seed, 0])
    cuts = scene_cuts(config)
    presence = np.ones((config.num_people, config.num_frames), bool)
    edges = [0, *cuts.tolist(), config.num_frames]
    for person, shot in config.only_in_one_shot:
        presence[person] = False
        presence[person, edges[shot]:edges[shot + 1]] = True
    for person, shot in config.absent_in_shots:
        presence[person, edges[shot]:edges[shot + 1]] = False
    if config.dialogue:
        from multithumbs.synth.dialogue import dialogue_layout

        K, R, t, dialogue_motions = dialogue_layout(config, rng, presence)
        cameras = CameraRig(K, R, t)
    else:
        cameras = _make_cameras(config, rng)
    centres = camera_centre(cameras.R, cameras.t)
    room = make_room(config.seed, *config.room_size)
    room = _clear_around(room, centres.reshape(-1, 3))
    crossing = config.crossing_pair
    # The abreast pair (and whoever passes them) is scripted from a random stream of its own; everybody
    # else walks at random as usual, but keeps out of their way (see _walk_clear_of).
    scripted = _abreast_motions(config, cuts, cameras) if config.abreast_pair is not None else {}
    motions = list(dialogue_motions) if config.dialogue else []
    for p in range(len(motions), config.num_people):
        if p in scripted:
            motions.append(scripted[p])
        elif crossing is not None and p in crossing:
            motions.append(_crossing_motion(config, cuts, crossing.index(p), rng))
        else:
            motions.append(_walk_clear_of(config, rng, p, scripted, presence, cameras, cuts))
    betas = np.clip(rng.normal(0, 0.8, (config.num_people, 10)), -2, 2)
    betas[:, 2:] *= 0.5
    clothing = _draw_clothing(rng, config.num_people, config.dressed_alike)
    for a, b in config.dressed_alike:  # dressed alike and built alike: only place and pose tell them apart
        betas[b] = betas[a]
    camera_ids = shot_camera_ids(config.num_frames, cuts, list(range(config.num_shots)))
    return Scene(config, room, tuple(motions), presence, betas, tuple(clothing), cameras, cuts, camera_ids)


def _clear_around(room: Room, camera_centres: np.ndarray, clearance: float = 0.6) -> Room:
    """Drop furniture that a camera would sit in or right behind."""
    keep = []
    for box in room.boxes:
        lo = np.asarray(box.centre) - np.asarray(box.size) / 2 - clearance
        hi = np.asarray(box.centre) + np.asarray(box.size) / 2 + clearance
        inside = np.all((camera_centres[:, :2] >= lo[:2]) & (camera_centres[:, :2] <= hi[:2]), axis=1)
        if not inside.any():
            keep.append(box)
    return dataclasses.replace(room, boxes=tuple(keep))


@dataclass(frozen=True)
class SyntheticVideo:
    """A rendered scene.

    Attributes:
        scene: what was decided before rendering.
        truth: the ground truth.
        frames: ``(T, H, W, 3)`` uint8 RGB.
        instance: ``(T, H, W)`` int8, person index per pixel, -1 for the room.
        boundary_depth: ``(C, 2, H, W)`` float32 z-depth at the boundary frames ``(t_b - 1, t_b)`` of each cut.
        vertices: ``(P, T, V, 3)`` float32 world vertices of every person.
        faces: ``(F, 3)`` mesh faces.
    """

    scene: Scene
    truth: GroundTruth
    frames: np.ndarray
    instance: np.ndarray
    boundary_depth: np.ndarray
    vertices: np.ndarray
    faces: np.ndarray

    def person_masks(self, person: int) -> np.ndarray:
        """``(T, H, ceil(W/8))`` bit-packed mask of one person over the video."""
        return pack_mask(self.instance == person)


def pose_people(scene: Scene, body: BodyModel) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """SMPL parameters and posed meshes of everyone, with feet on the floor.

    Returns:
        global_orient ``(P, T, 3)``, body_pose ``(P, T, 23, 3)``, transl ``(P, T, 3)``,
        vertices ``(P, T, V, 3)``, joints ``(P, T, 24, 3)``, all world frame.
    """
    orients, poses = zip(*(motion_to_smpl(m) for m in scene.motions))
    global_orient, body_pose = np.stack(orients), np.stack(poses)
    p, t = global_orient.shape[:2]
    betas = np.broadcast_to(scene.betas[:, None], (p, t, 10))
    with torch.no_grad():
        out = body.forward(global_orient, body_pose, betas, None)
    verts, joints = out.vertices.double().numpy(), out.joints.double().numpy()
    # Stand on the floor: the lowest vertex of every frame touches z = 0; pelvis over its floor position.
    floor_xy = np.stack([m.position for m in scene.motions])
    offset = np.concatenate([floor_xy - joints[:, :, 0, :2], -verts[..., 2].min(axis=2, keepdims=True)], axis=2)
    transl = offset
    return (global_orient, body_pose, transl, (verts + transl[:, :, None]).astype(np.float32),
            joints + transl[:, :, None])


def synthesize(config: SceneConfig, body: BodyModel, progress=None) -> SyntheticVideo:
    """Build, pose, render and splice a scene; assemble its ground truth.

    Args:
        progress: optional callable ``progress(done, total)`` called after each rendered frame.
    """
    scene = build_scene(config)
    global_orient, body_pose, transl, vertices, joints = pose_people(scene, body)
    h, w = config.image_size
    K = splice_views(np.repeat(scene.cameras.K[:, None], config.num_frames, 1), scene.camera_ids)
    R = splice_views(scene.cameras.R, scene.camera_ids)
    t = splice_views(scene.cameras.t, scene.camera_ids)
    p_count, t_count = scene.presence.shape
    with torch.no_grad():
        rest = body.forward(np.zeros(3), np.zeros((23, 3)), np.zeros(10)).vertices.double().numpy()
    colors = [c.vertex_colors(body.part_labels, rest, float(rest[:, 1].max())) for c in scene.clothing]

    frames = np.zeros((t_count, h, w, 3), np.uint8)
    instance = np.full((t_count, h, w), -1, np.int8)
    boundary = {int(f) for c in scene.cut_frames for f in (c - 1, c)}
    depth_at: dict[int, np.ndarray] = {}
    for f in range(t_count):
        people = [q for q in range(p_count) if scene.presence[q, f]]
        meshes = [MeshInstance(vertices[q, f], body.faces, colors[q]) for q in people]
        render: Render = render_view(scene.room, meshes, K[f], R[f], t[f], (h, w))
        frames[f] = render.rgb
        ids = np.asarray(people + [-1], np.int8)  # render indices -> person indices; -1 stays room
        instance[f] = ids[render.instance]
        if f in boundary:
            depth_at[f] = render.depth.astype(np.float32)
        if progress is not None:
            progress(f + 1, t_count)
    boundary_depth = np.stack([np.stack([depth_at[int(c) - 1], depth_at[int(c)]]) for c in scene.cut_frames]) \
        if scene.cut_frames.size else np.zeros((0, 2, h, w), np.float32)

    keypoints, bboxes, visible = _observe(joints, scene.presence, instance, K, R, t)
    id_map = np.array([[s, q, q] for s in range(config.num_shots) for q in range(p_count)
                       if scene.presence[q][scene.camera_ids == s].any()], dtype=np.int64).reshape(-1, 3)
    world = WorldResult(
        person_ids=np.arange(p_count), global_orient=global_orient, body_pose=body_pose, betas=scene.betas,
        transl=transl, valid=scene.presence.copy(), K=K, R=R, t=t, cut_frames=scene.cut_frames,
        fps=config.fps, image_size=(h, w), id_map=id_map, keypoints2d=keypoints)
    metadata = {"kind": "synthetic", "name": config.name, "seed": config.seed, "body_model": body.source,
                "config": config_to_json(config)}
    truth = GroundTruth(world, bboxes, visible, scene.camera_ids, metadata)
    return SyntheticVideo(scene, truth, frames, instance, boundary_depth, vertices, body.faces)


def _observe(joints: np.ndarray, presence: np.ndarray, instance: np.ndarray, K, R, t,
             min_pixels: int = 30) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """True 2D joints with visibility, boxes of the visible body and visibility per person and frame."""
    p_count, t_count = presence.shape
    h, w = instance.shape[1:]
    uv = project_points(joints, K[None], R[None], t[None])  # (P, T, 24, 2)
    z = world_to_camera(joints, R[None], t[None])[..., 2]
    bboxes = np.zeros((p_count, t_count, 4))
    visible = np.zeros((p_count, t_count), bool)
    conf = np.zeros((p_count, t_count, 24))
    for q in range(p_count):
        mask = instance == q
        counts = mask.reshape(t_count, -1).sum(1)
        visible[q] = presence[q] & (counts >= min_pixels)
        for f in np.nonzero(visible[q])[0]:
            ys, xs = np.nonzero(mask[f])
            bboxes[q, f] = xs.min(), ys.min(), xs.max() + 1, ys.max() + 1
        ui, vi = np.round(uv[q, ..., 0]).astype(int), np.round(uv[q, ..., 1]).astype(int)
        inside = (ui >= 0) & (ui < w) & (vi >= 0) & (vi < h) & (z[q] > 0.05) & presence[q][:, None]
        # A joint is visible when the pixel it projects to shows this person, or nothing in front of it:
        # joints sit inside the body, so look at a small window around the projection.
        seen = np.zeros_like(inside)
        fi, ji = np.nonzero(inside)
        for dy in (-2, 0, 2):
            for dx in (-2, 0, 2):
                yy, xx = np.clip(vi[fi, ji] + dy, 0, h - 1), np.clip(ui[fi, ji] + dx, 0, w - 1)
                seen[fi, ji] |= instance[fi, yy, xx] == q
        conf[q] = seen.astype(float)
    keypoints = np.concatenate([uv, conf[..., None]], axis=-1)
    return keypoints, bboxes, visible
