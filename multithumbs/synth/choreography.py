"""Scripted walks of the synthetic scenes: two people crossing at the first cut, a pair walking abreast
through it (with a partner passing them), and random walks that keep out of the scripted people's way
without hiding them from the cameras near a cut.
"""

from __future__ import annotations

import itertools
from typing import TYPE_CHECKING

import numpy as np

from multithumbs.errors import InputError
from multithumbs.geometry import camera_centre
from multithumbs.synth.config import SceneConfig
from multithumbs.synth.motion import PersonMotion, simulate_walk, straight_walk, walk_abreast

if TYPE_CHECKING:  # scene.py imports this module
    from multithumbs.synth.scene import CameraRig


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
