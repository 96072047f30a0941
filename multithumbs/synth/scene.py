"""The synthetic multi-shot world (DESIGN §7): a textured room, people, cameras, and the rendered video.

``build_scene`` decides everything (room, people's motion and clothing, cameras, cuts) from a
:class:`SceneConfig` and its seed; ``synthesize`` poses the bodies, renders the spliced multi-shot
video with exact depth and instance masks, and assembles the :class:`GroundTruth`.
"""

from __future__ import annotations

import dataclasses
import itertools
from dataclasses import dataclass

import numpy as np
import torch

from multithumbs.body.model import BodyModel
from multithumbs.errors import InputError
from multithumbs.geometry import camera_centre, intrinsics_from_fov, look_at, project_points, world_to_camera
# The settings and their JSON form live without torch in multithumbs.synth.config; re-exported here.
from multithumbs.synth.config import MotionConfig, SceneConfig, config_from_json, config_to_json  # noqa: F401
from multithumbs.synth.motion import (PersonMotion, motion_to_smpl, simulate_walk, straight_walk,
                                      walk_abreast)
from multithumbs.synth.render import MeshInstance, Render, render_view
from multithumbs.synth.room import Room, make_room
from multithumbs.synth.splice import even_cuts, shot_camera_ids, splice_views
from multithumbs.types import GroundTruth, WorldResult, pack_mask


# Clothing regions by the SMPL joint that drives a vertex.
_SKIN_PARTS = (12, 15, 20, 21, 22, 23)
_TOP_PARTS = (3, 6, 9, 13, 14, 16, 17)
_SLEEVE_PARTS = (18, 19)
_BOTTOM_PARTS = (0, 1, 2, 4, 5)
_SHOE_PARTS = (7, 8, 10, 11)
_SKIN_TONES = np.array([[0.96, 0.80, 0.69], [0.87, 0.67, 0.52], [0.68, 0.48, 0.34],
                        [0.45, 0.31, 0.22], [0.92, 0.74, 0.60]])
_HAIR = np.array([[0.08, 0.06, 0.05], [0.35, 0.22, 0.12], [0.75, 0.6, 0.35], [0.2, 0.2, 0.2]])
_GARMENTS = np.array([  # saturated and neutral clothing colours, distinct in hue
    [0.80, 0.12, 0.12], [0.10, 0.35, 0.80], [0.12, 0.62, 0.22], [0.95, 0.75, 0.10], [0.55, 0.20, 0.65],
    [0.95, 0.45, 0.10], [0.10, 0.65, 0.70], [0.90, 0.90, 0.88], [0.15, 0.15, 0.18], [0.60, 0.40, 0.25],
    [0.95, 0.55, 0.70], [0.30, 0.30, 0.55],
])

# The dressed-alike pairs' uniform: a charcoal suit, darker trousers, black shoes (all neutral grey).
_UNIFORM_TOP = np.array([0.30, 0.30, 0.30])
_UNIFORM_BOTTOM = np.array([0.20, 0.20, 0.20])
_UNIFORM_SHOES = np.array([0.08, 0.08, 0.08])


@dataclass(frozen=True)
class Clothing:
    """Colours of one person (RGB in [0, 1]).

    Attributes:
        skin, hair, top, sleeves, bottom, shoes: ``(3,)`` each.
    """

    skin: np.ndarray
    hair: np.ndarray
    top: np.ndarray
    sleeves: np.ndarray
    bottom: np.ndarray
    shoes: np.ndarray

    def vertex_colors(self, part_labels: np.ndarray, rest_vertices: np.ndarray, head_top: float) -> np.ndarray:
        """``(V, 3)`` colours from each vertex's part (and hair on the top of the head)."""
        colors = np.tile(self.skin, (part_labels.shape[0], 1))
        for parts, color in ((_TOP_PARTS, self.top), (_SLEEVE_PARTS, self.sleeves),
                             (_BOTTOM_PARTS, self.bottom), (_SHOE_PARTS, self.shoes)):
            colors[np.isin(part_labels, parts)] = color
        head = part_labels == 15
        hair = head & (rest_vertices[:, 1] > head_top - 0.09) | head & (rest_vertices[:, 2] < rest_vertices[head, 2].mean() - 0.04)
        colors[hair] = self.hair
        return colors


def _draw_clothing(rng: np.random.Generator, num_people: int, alike: tuple[tuple[int, int], ...]) -> list[Clothing]:
    tops = rng.permutation(len(_GARMENTS))
    bottoms = rng.permutation(len(_GARMENTS))
    out = []
    for p in range(num_people):
        top = _GARMENTS[tops[p % len(tops)]]
        bottom = _GARMENTS[bottoms[(p + 3) % len(bottoms)]] * 0.7  # trousers a bit darker
        sleeves = top if rng.random() < 0.6 else _SKIN_TONES[rng.integers(len(_SKIN_TONES))]
        out.append(Clothing(_SKIN_TONES[rng.integers(len(_SKIN_TONES))], _HAIR[rng.integers(len(_HAIR))],
                            top, sleeves, bottom, np.array([0.12, 0.1, 0.09]) + 0.3 * rng.random() * np.ones(3)))
    for a, b in alike:
        # A uniform: both wear the same achromatic suit (no hue for a colour descriptor to key on, and grey
        # stays grey however the light falls on it) and the same skin, with shaven heads (hair = skin), so
        # the head looks the same from the front and the back: appearance alone cannot tell them apart,
        # whichever way each faces. The draws above are kept so everybody else dresses as before.
        skin = out[a].skin
        out[a] = out[b] = Clothing(skin, skin, _UNIFORM_TOP, _UNIFORM_TOP, _UNIFORM_BOTTOM, _UNIFORM_SHOES)
    return out


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


def _crossing_motion(config: SceneConfig, cuts: np.ndarray, which: int, rng: np.random.Generator) -> PersonMotion:
    """Two people walking towards each other on parallel lines 0.5 m apart, passing at the first cut."""
    t_meet = (cuts[0] if cuts.size else config.num_frames // 2) / config.fps
    speed = float(np.clip(1.8 / max(t_meet, 1e-3), 0.6, 1.3))
    angle = np.deg2rad(20.0) + rng.uniform(-0.2, 0.2) * 0  # one shared line direction for the pair
    along = np.array([np.cos(angle), np.sin(angle)])
    across = np.array([-along[1], along[0]])
    sign = 1.0 if which == 0 else -1.0
    start = -sign * speed * t_meet * along + sign * 0.25 * across
    end = sign * 3.0 * along + sign * 0.25 * across
    return simulate_walk(start, [end], config.num_frames, config.fps, rng, config.motion, speed=speed,
                         allow_pauses=False)


def _frame_cameras(config: SceneConfig, cameras: CameraRig, cuts: np.ndarray) -> np.ndarray:
    """``(T, 2)`` floor position of the camera filming each frame."""
    frames = np.arange(config.num_frames)
    shot = np.searchsorted(cuts, frames, side="right")
    return camera_centre(cameras.R[shot, frames], cameras.t[shot, frames])[:, :2]


def _hidden_fraction(pos_a: np.ndarray, pos_b: np.ndarray, camera: np.ndarray, half_width: float = 0.25
                     ) -> np.ndarray:
    """``(T,)`` fraction of the narrower person's width that the other covers, seen from ``camera (T, 2)``.

    People are discs of ``half_width`` on the floor at ``pos_a, pos_b (T, 2)``; widths are angles about the
    camera centre.
    """
    angle, half = [], []
    for pos in (pos_a, pos_b):
        rel = pos - camera
        dist = np.linalg.norm(rel, axis=1)
        angle.append(np.arctan2(rel[:, 1], rel[:, 0]))
        half.append(np.arcsin(half_width / np.maximum(dist, half_width)))
    apart = np.abs((angle[0] - angle[1] + np.pi) % (2 * np.pi) - np.pi)
    covered = np.clip(half[0] + half[1] - apart, 0, None)
    return np.minimum(covered / (2 * np.minimum(half[0], half[1])), 1.0)


# A passer-by keeps this far (m, pelvis to pelvis) from scripted people and hides at most this fraction of
# their width (or is hidden that much) in any frame.
_CLEARANCE, _MAX_HIDDEN = 0.8, 0.3


def _abreast_motions(config: SceneConfig, cuts: np.ndarray, cameras: CameraRig, min_camera_distance: float = 2.4,
                     pass_offset: float = 0.6) -> dict[int, PersonMotion]:
    """Motions of ``config.abreast_pair`` (and of a crossing partner passing them), by person index.

    The pair walks away from the cameras of the first cut, 30 degrees off their mean floor view direction
    (to a side drawn from the pair's own random stream), the midpoint passing 0.3 m beyond the scene centre
    at the cut. They walk only where both stay inside ``config.motion.region`` and at least
    ``min_camera_distance`` from those cameras, standing together before and after. Where one of them would
    hide the other from some frame's camera, the other side and then 20 and 40 degrees are tried. A crossing
    partner walks the other way on a line ``pass_offset`` outside its abreast person's, passing them at the
    cut, within the same limits.
    """
    rng = np.random.default_rng([config.seed, 2])
    cut = int(cuts[0]) if cuts.size else config.num_frames // 2
    views = [(0, max(cut - 1, 0))] + ([(1, cut)] if config.num_shots > 1 else [])
    frame_camera = _frame_cameras(config, cameras, cuts)
    centres = frame_camera[[f for _, f in views]]
    forward = sum(cameras.R[k, f, 2, :2] for k, f in views)  # camera +z (viewing axis) on the floor
    forward = forward / np.linalg.norm(forward)
    a, b = config.abreast_pair
    partner = passed = None
    if config.crossing_pair is not None and set(config.crossing_pair) & {a, b}:
        passed = next(p for p in config.crossing_pair if p in (a, b))
        partner = next(p for p in config.crossing_pair if p != passed)

    def walkable(points: list[np.ndarray], direction: np.ndarray) -> tuple[float, float] | None:
        """The stretch around 0 of the lines through ``points`` (signed distance along ``direction``)
        where every point stays in the region and away from the cameras; None when 0 is not in it."""
        s = np.linspace(-8.0, 8.0, 1601)
        ok = np.ones_like(s, bool)
        for point in points:
            pos = point[None] + s[:, None] * direction[None]
            ok &= np.all(np.abs(pos) <= np.asarray(config.motion.region), axis=1)
            ok &= np.linalg.norm(pos[:, None] - centres[None], axis=2).min(axis=1) >= min_camera_distance
        zero = len(s) // 2
        if not ok[zero]:
            return None
        lo = zero - np.argmin(ok[zero::-1]) + 1 if not ok[:zero + 1].all() else 0
        hi = zero + np.argmin(ok[zero:]) - 1 if not ok[zero:].all() else len(s) - 1
        return float(s[lo]), float(s[hi])

    side = float(rng.choice([-1.0, 1.0]))
    speed = float(np.clip(config.motion.walk_speed + config.motion.walk_speed_spread * rng.standard_normal(),
                          0.5, 1.8))
    partner_speed = float(np.clip(config.motion.walk_speed + config.motion.walk_speed_spread
                                  * rng.standard_normal(), 0.5, 1.8))
    phase_seed = int(rng.integers(2**31))
    at_time = cut / config.fps
    for offset_deg, sign in itertools.product((30.0, 20.0, 40.0), (side, -side)):
        heading = float(np.arctan2(forward[1], forward[0]) + sign * np.deg2rad(offset_deg))
        along = np.array([np.cos(heading), np.sin(heading)])
        left = np.array([-along[1], along[0]])
        through = 0.3 * forward
        lines = {a: through + 0.5 * config.abreast_spacing * left, b: through - 0.5 * config.abreast_spacing * left}
        path = walkable([lines[a], lines[b]], along)
        if path is None:
            continue
        gait = np.random.default_rng(phase_seed)  # the same gait phases whichever heading is taken
        pair = walk_abreast(through, heading, at_time, config.abreast_spacing, config.num_frames, config.fps, gait,
                            config.motion, speed=speed, path=path)
        if _hidden_fraction(pair[0].position, pair[1].position, frame_camera).max() > _MAX_HIDDEN:
            continue
        out = {a: pair[0], b: pair[1]}
        if partner is not None:
            outward = (lines[passed] - through) / np.linalg.norm(lines[passed] - through)
            partner_line = lines[passed] + pass_offset * outward
            partner_path = walkable([partner_line], -along)
            if partner_path is None:
                continue
            out[partner] = straight_walk(partner_line, heading + np.pi, at_time, config.num_frames, config.fps,
                                         partner_speed, gait, config.motion, path=partner_path)
        return out
    raise InputError(f"scene {config.name or 'config'}: abreast_pair cannot walk through the scene centre, "
                     f"both in view, inside motion.region {config.motion.region}")


def _walk_clear_of(config: SceneConfig, rng: np.random.Generator, person: int, scripted: dict[int, PersonMotion],
                   presence: np.ndarray, cameras: CameraRig, cuts: np.ndarray, tries: int = 200) -> PersonMotion:
    """A random walk (start and three waypoints in the region) that keeps out of the ``scripted`` people's way.

    Walks are drawn until one keeps ``_CLEARANCE`` from every scripted person and neither hides the other
    more than ``_MAX_HIDDEN`` in any frame both are present; after ``tries`` draws the one with the fewest
    frames too close, then hiding within a second of a cut, then hiding at all, is taken (a passer-by may
    briefly hide someone mid-shot, not at a cut). Without scripted people this is the first draw.
    """
    region = np.asarray(config.motion.region)
    frame_camera = _frame_cameras(config, cameras, cuts) if scripted else None
    near_cut = np.zeros(config.num_frames, bool)
    for cut in cuts:
        near_cut[max(0, int(cut) - round(config.fps)):int(cut) + round(config.fps)] = True
    best, best_bad = None, (np.inf, np.inf, np.inf)
    for _ in range(tries):
        start = rng.uniform(-1, 1, 2) * region
        waypoints = [rng.uniform(-1, 1, 2) * region for _ in range(3)]
        walk = simulate_walk(start, waypoints, config.num_frames, config.fps, rng, config.motion)
        close = np.zeros(config.num_frames, bool)
        hidden = np.zeros(config.num_frames, bool)
        for q, other in scripted.items():
            both = presence[person] & presence[q]
            close |= both & (np.linalg.norm(walk.position - other.position, axis=1) < _CLEARANCE)
            hidden |= both & (_hidden_fraction(walk.position, other.position, frame_camera) > _MAX_HIDDEN)
        score = (int(close.sum()), int((hidden & near_cut).sum()), int(hidden.sum()))
        if score == (0, 0, 0):
            return walk
        if score < best_bad:
            best, best_bad = walk, score
    return best


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
