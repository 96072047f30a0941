"""The procedural body's proportions and surface (:mod:`multithumbs.body.procedural` builds the SMPL arrays
from them): the rest skeleton from interpretable :class:`Proportions`, closed tube meshes swept along
polylines through its joints with superellipse cross-sections, mirrored left to right, stretched to a height.
SMPL's body frame throughout (+y up, facing +z, left +x).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from multithumbs.conventions import NUM_JOINTS, SMPL_PARENTS

SOLE_HEIGHT = -0.95
"""``y`` of the soles in the body frame (metres), the same for every shape."""

ANKLE_HEIGHT = 0.08
"""Height of the ankle joints above the soles (metres)."""

NEUTRAL_JOINTS = np.array([
    [0.000, 0.000, 0.000],    # 0 pelvis
    [0.090, -0.090, 0.000],   # 1 left hip
    [-0.090, -0.090, 0.000],  # 2 right hip
    [0.000, 0.110, -0.020],   # 3 spine1
    [0.100, -0.470, 0.010],   # 4 left knee
    [-0.100, -0.470, 0.010],  # 5 right knee
    [0.000, 0.245, 0.000],    # 6 spine2
    [0.090, -0.870, -0.030],  # 7 left ankle
    [-0.090, -0.870, -0.030],  # 8 right ankle
    [0.000, 0.305, 0.005],    # 9 spine3
    [0.110, -0.930, 0.090],   # 10 left foot (ball of the foot)
    [-0.110, -0.930, 0.090],  # 11 right foot
    [0.000, 0.520, -0.040],   # 12 neck
    [0.075, 0.430, -0.040],   # 13 left collar
    [-0.075, 0.430, -0.040],  # 14 right collar
    [0.000, 0.610, 0.010],    # 15 head
    [0.175, 0.455, -0.045],   # 16 left shoulder
    [-0.175, 0.455, -0.045],  # 17 right shoulder
    [0.435, 0.445, -0.060],   # 18 left elbow
    [-0.435, 0.445, -0.060],  # 19 right elbow
    [0.685, 0.450, -0.060],   # 20 left wrist
    [-0.685, 0.450, -0.060],  # 21 right wrist
    [0.770, 0.445, -0.065],   # 22 left hand (knuckles)
    [-0.770, 0.445, -0.065],  # 23 right hand
])
"""``(24, 3)`` rest joints of the mean body (metres, SMPL-like proportions, 1.70 m tall)."""

LEFT_TO_RIGHT = {1: 2, 4: 5, 7: 8, 10: 11, 13: 14, 16: 17, 18: 19, 20: 21, 22: 23}
"""Left joint index -> its mirror on the right."""


@dataclass(frozen=True)
class Proportions:
    """Interpretable body measurements the procedural body is generated from (mean body = defaults).

    Attributes:
        height: vertical stretch about the soles (1 = 1.70 m).
        girth: multiplier of the torso, neck and limb cross-sections.
        leg_length: multiplier of the thigh and shin bones (the body above rises, soles stay).
        arm_length: multiplier of the upper arm, forearm and hand.
        shoulder_width: multiplier of the collar/shoulder offsets and of the upper torso's width.
        hip_width: multiplier of the hip joint offsets and of the lower torso's width.
        head_size: multiplier of the head about the head joint.
        belly: extra forward bulge of the abdomen (metres).
        torso_length: multiplier of the spine bones (pelvis to neck).
        limb_thickness: multiplier of the arm and leg cross-sections.
    """

    height: float = 1.0
    girth: float = 1.0
    leg_length: float = 1.0
    arm_length: float = 1.0
    shoulder_width: float = 1.0
    hip_width: float = 1.0
    head_size: float = 1.0
    belly: float = 0.0
    torso_length: float = 1.0
    limb_thickness: float = 1.0


BETA_DIRECTIONS: tuple[tuple[str, float], ...] = (
    ("height", 0.035),          # 0: ~6 cm taller per unit
    ("girth", 0.08),            # 1: cross-sections 8 % wider per unit
    ("leg_length", 0.05),       # 2: ~4 cm longer legs per unit
    ("arm_length", 0.05),       # 3: ~3 cm longer arms per unit
    ("shoulder_width", 0.07),   # 4
    ("hip_width", 0.07),        # 5
    ("head_size", 0.05),        # 6
    ("belly", 0.015),           # 7: 1.5 cm more belly per unit
    ("torso_length", 0.04),     # 8
    ("limb_thickness", 0.06),   # 9
)
"""What ``betas[k]`` means: ``(Proportions field, change per unit of beta)``."""


@dataclass(frozen=True)
class _Tube:
    """A closed tube swept along a polyline of knots, with elliptical-ish cross-sections.

    Attributes:
        knots: ``(K, 3)`` axis polyline.
        stations: rings per segment, ``K - 1`` entries (topology: never depends on the shape).
        profile: ``(C, 4)`` control rows ``(u, radius_a, radius_b, offset_b)`` over the knot coordinate
            ``u`` (knot index plus fraction); ``b`` is the hint direction made normal to the axis,
            ``a = b x tangent``.
        caps: lengths of the rounded start and end caps beyond the first and last knot.
        cap_rings: ``(start, end)`` rings per cap, the pole included.
        around: vertices per ring.
        hint: ``(3,)`` direction the ``b`` axis of cross-sections leans to.
        exponent: superellipse exponent of cross-sections (2 = ellipse, larger = boxier).
        owners: ``K + 1`` joints owning the start cap, each segment, and the end cap.
        blend: ``K`` half-widths (metres) of the parent/child weight blend at each knot.
        joint_knots: ``(joint, knot)`` pairs: the ring at ``knot`` regresses ``joint``.
        mirrored: also add the tube's mirror image (x -> -x) for the body's right side.
    """

    knots: np.ndarray
    stations: tuple[int, ...]
    profile: np.ndarray
    caps: tuple[float, float]
    cap_rings: tuple[int, int]
    around: int
    hint: tuple[float, float, float]
    exponent: float
    owners: tuple[int, ...]
    blend: tuple[float, ...]
    joint_knots: tuple[tuple[int, int], ...]
    mirrored: bool = False


@dataclass(frozen=True)
class _TubeMesh:
    """A tube's surface. ``vertices (N, 3)``, ``faces (F, 3)`` local indices, ``axial (N,)`` arc length
    along the axis (negative in the start cap), ``knot_axial (K,)``, ``rings`` maps knot -> vertex ids."""

    vertices: np.ndarray
    faces: np.ndarray
    axial: np.ndarray
    knot_axial: np.ndarray
    rings: dict[int, np.ndarray]


def _smoothstep(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def _ramp(u: np.ndarray, start: float, end: float) -> np.ndarray:
    """0 before ``start``, 1 after ``end``, linear between (either order)."""
    return np.clip((u - start) / (end - start), 0.0, 1.0)


def _skeleton(p: Proportions) -> np.ndarray:
    """``(24, 3)`` rest joints of the body with proportions ``p``, before the height stretch."""
    parents = np.array(SMPL_PARENTS)
    bones = NEUTRAL_JOINTS.copy()
    bones[1:] -= NEUTRAL_JOINTS[parents[1:]]
    for j in (1, 2):
        bones[j, 0] *= p.hip_width
    for j in (4, 5, 7, 8):
        bones[j] *= p.leg_length
    for j in (3, 6, 9, 12):
        bones[j] *= p.torso_length
    for j in (13, 14):
        bones[j] *= (p.shoulder_width, p.torso_length, p.torso_length)
    for j in (16, 17):
        bones[j, 0] *= p.shoulder_width
    for j in (18, 19, 20, 21, 22, 23):
        bones[j] *= p.arm_length
    joints = np.zeros_like(bones)
    for j in range(NUM_JOINTS):  # parents precede children in SMPL order
        joints[j] = bones[j] + (joints[parents[j]] if j else 0.0)
    # Stand on the same floor whatever the proportions.
    joints[:, 1] += SOLE_HEIGHT + ANKLE_HEIGHT - joints[7, 1]
    return joints


def _tubes(p: Proportions) -> list[_Tube]:
    """The body's tubes (left limbs only; they are mirrored) for proportions ``p``."""
    J = _skeleton(p)
    up, front = (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)
    limb = p.girth * p.limb_thickness

    # Torso: hip level -> pelvis -> spine1 -> spine2 -> spine3 -> under the neck.
    torso_knots = np.stack([J[0] + (0.0, -0.09, 0.0), J[0], J[3], J[6], J[9],
                            J[9] + np.array([0.0, 0.135, -0.04]) * p.torso_length])
    torso = np.array([  # u, half width (x), half depth (z), forward shift of the centre
        [0.0, 0.160, 0.095, -0.012],
        [0.5, 0.165, 0.105, -0.010],
        [1.0, 0.160, 0.105, 0.000],
        [1.6, 0.146, 0.100, 0.010],
        [2.0, 0.140, 0.098, 0.010],
        [3.0, 0.160, 0.108, 0.005],
        [4.0, 0.170, 0.112, 0.010],
        [4.5, 0.180, 0.105, 0.005],
        [5.0, 0.185, 0.085, 0.000],
    ])
    u = torso[:, 0]
    belly_bump = np.interp(u, [0.8, 1.6, 2.2, 3.2], [0.0, 1.0, 0.9, 0.0])
    # The belly pushes the front out (centre forward and depth up by half each: the back stays) and
    # rounds the waist.
    torso[:, 2:4] += 0.5 * p.belly * belly_bump[:, None]
    torso[:, 1] += 0.5 * p.belly * belly_bump
    torso[:, 1] *= 1 + (p.shoulder_width - 1) * _ramp(u, 3.0, 4.5) + (p.hip_width - 1) * _ramp(u, 2.0, 1.0)
    torso[:, 1:] *= p.girth

    leg = np.array([  # u, half width (x), half depth (z), forward shift
        [0.00, 0.085, 0.090, 0.000],
        [0.25, 0.078, 0.082, 0.005],
        [0.75, 0.058, 0.060, 0.000],
        [1.00, 0.050, 0.053, 0.000],
        [1.25, 0.053, 0.058, -0.012],  # calf
        [1.50, 0.048, 0.052, -0.008],
        [1.85, 0.036, 0.038, 0.000],
        [2.00, 0.036, 0.040, 0.000],
    ])
    leg[:, 1:] *= limb

    arm = np.array([  # u, half height (y), half depth (z), forward shift
        [0.0, 0.050, 0.050, 0.0],  # collar
        [1.0, 0.052, 0.052, 0.0],  # shoulder
        [1.25, 0.048, 0.047, 0.0],
        [1.8, 0.038, 0.038, 0.0],
        [2.0, 0.036, 0.036, 0.0],  # elbow
        [2.3, 0.040, 0.042, 0.0],
        [2.8, 0.027, 0.032, 0.0],
        [3.0, 0.022, 0.030, 0.0],  # wrist: palm down, flat
        [3.5, 0.017, 0.042, 0.0],
        [4.0, 0.015, 0.045, 0.0],  # knuckles
        [4.5, 0.012, 0.040, 0.0],
        [5.0, 0.010, 0.032, 0.0],  # finger tips
    ])
    arm[:, 1:] *= 1 + (limb - 1) * _ramp(arm[:, 0], 3.2, 2.8)[:, None]  # hands keep their size

    neck = np.array([[0.0, 0.058, 0.055, 0.0], [1.0, 0.052, 0.050, 0.0], [2.0, 0.048, 0.048, 0.0]])
    neck[:, 1:] *= p.girth

    head = np.array([  # u, half width (x), half depth (z), forward shift
        [0.0, 0.055, 0.070, 0.010],  # jaw
        [1.0, 0.072, 0.092, 0.000],  # head joint, ear level
        [1.6, 0.078, 0.098, 0.000],
        [2.0, 0.077, 0.097, 0.000],
    ])
    head[:, 1:] *= p.head_size

    foot = np.array([  # u, half width (x), half height (y), upward shift
        [0.0, 0.030, 0.045, 0.0],  # heel
        [1.0, 0.038, 0.050, 0.0],  # under the ankle
        [2.0, 0.047, 0.020, 0.0],  # ball of the foot
        [3.0, 0.040, 0.017, 0.0],  # toes
    ])

    return [
        _Tube(torso_knots, (3, 4, 5, 2, 5), torso, (0.07, 0.05), (4, 4), 28, front, 2.4,
              owners=(0, 0, 0, 3, 6, 9, 9), blend=(0.0, 0.0, 0.05, 0.05, 0.03, 0.0),
              joint_knots=((0, 1), (3, 2), (6, 3), (9, 4))),
        _Tube(np.stack([J[12] + (0.0, -0.09, -0.01), J[12], J[15]]), (3, 3), neck, (0.03, 0.02),
              (3, 3), 16, front, 2.0, owners=(9, 9, 12, 15), blend=(0.0, 0.03, 0.03),
              joint_knots=((12, 1),)),
        _Tube(np.stack([J[15] + np.array([0.0, -0.045, 0.015]) * p.head_size, J[15],
                        J[15] + np.array([0.0, 0.06, 0.0]) * p.head_size]),
              (3, 4), head, (0.035 * p.head_size, 0.08 * p.head_size), (4, 6), 24, front, 2.0,
              owners=(15, 15, 15, 15), blend=(0.0, 0.0, 0.0), joint_knots=((15, 1),)),
        _Tube(np.stack([J[1], J[4], J[7]]), (13, 13), leg, (0.085 * limb, 0.035), (5, 3), 16, front,
              2.0, owners=(0, 1, 4, 7), blend=(0.06, 0.05, 0.03),
              joint_knots=((1, 0), (4, 1), (7, 2)), mirrored=True),
        _Tube(np.stack([J[7] + (0.0, -0.035, -0.045), J[7] + (0.005, -0.03, 0.03), J[10],
                        J[10] + (0.008, -0.003, 0.055)]), (2, 4, 2), foot, (0.03, 0.025), (3, 3),
              16, up, 2.2, owners=(7, 7, 7, 10, 10), blend=(0.0, 0.0, 0.025, 0.0),
              joint_knots=((10, 2),), mirrored=True),
        _Tube(np.stack([J[13], J[16], J[18], J[20], J[22],
                        J[22] + np.array([0.08, -0.005, 0.0]) * p.arm_length]),
              (3, 9, 9, 3, 3), arm, (0.04, 0.02), (3, 3), 16, front, 2.0,
              owners=(9, 13, 16, 18, 20, 22, 22), blend=(0.03, 0.05, 0.04, 0.025, 0.02, 0.0),
              joint_knots=((13, 0), (16, 1), (18, 2), (20, 3), (22, 4)), mirrored=True),
    ]


def _sweep(tube: _Tube) -> _TubeMesh:
    """Mesh of one tube: rings of ``around`` vertices at each station plus a pole at each end."""
    knots = tube.knots
    n_knots = len(knots)
    # Station coordinates u (knot index + fraction): a fixed count per segment, plus the last knot.
    u = np.concatenate([i + np.arange(n) / n for i, n in enumerate(tube.stations)] + [[n_knots - 1.0]])
    seg = np.minimum(np.floor(u).astype(int), n_knots - 2)
    centres = knots[seg] + (u - seg)[:, None] * (knots[seg + 1] - knots[seg])
    tangents = np.gradient(centres, axis=0)
    tangents /= np.linalg.norm(tangents, axis=1, keepdims=True)
    from scipy.interpolate import PchipInterpolator  # here: finding the cached body's file needs no scipy

    ctrl = tube.profile
    ra, rb, ob = (PchipInterpolator(ctrl[:, 0], ctrl[:, c])(u) for c in (1, 2, 3))
    axial = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(centres, axis=0), axis=1))])
    stations = (centres, tangents, ra, rb, ob, axial)

    def cap(end: int, sign: float, length: float, rings: int) -> tuple[np.ndarray, ...]:
        """Rings of a rounded cap (quarter-ellipse profile) beyond station ``end``, pole excluded."""
        alpha = np.arange(1, rings) / rings * (np.pi / 2)
        reach = sign * length * np.sin(alpha)
        return (centres[end] + reach[:, None] * tangents[end], np.repeat(tangents[end][None], rings - 1, 0),
                ra[end] * np.cos(alpha), rb[end] * np.cos(alpha), np.full(rings - 1, ob[end]), axial[end] + reach)

    start_cap = cap(0, -1.0, tube.caps[0], tube.cap_rings[0])
    end_cap = cap(-1, 1.0, tube.caps[1], tube.cap_rings[1])
    # All rings from the start pole to the end pole.
    ring_c, ring_t, ring_a, ring_b, ring_o, ring_s = (
        np.concatenate([first[::-1], middle, last]) for first, middle, last in zip(start_cap, stations, end_cap))
    hint = np.asarray(tube.hint, float)
    b_axis = hint - (ring_t @ hint)[:, None] * ring_t
    b_axis /= np.linalg.norm(b_axis, axis=1, keepdims=True)
    a_axis = np.cross(b_axis, ring_t)

    theta = 2 * np.pi * np.arange(tube.around) / tube.around
    power = 2.0 / tube.exponent  # superellipse |x/a|^n + |y/b|^n = 1
    cos_p = np.sign(np.cos(theta)) * np.abs(np.cos(theta)) ** power
    sin_p = np.sign(np.sin(theta)) * np.abs(np.sin(theta)) ** power
    rings = ((ring_c + ring_o[:, None] * b_axis)[:, None]
             + (ring_a[:, None] * cos_p)[..., None] * a_axis[:, None]
             + (ring_b[:, None] * sin_p)[..., None] * b_axis[:, None])
    n_rings, m = len(ring_c), tube.around
    # Cap rings share their end station's tangent, hence its cross-section frame.
    pole0 = centres[0] + ob[0] * b_axis[0] - tube.caps[0] * tangents[0]
    pole1 = centres[-1] + ob[-1] * b_axis[-1] + tube.caps[1] * tangents[-1]
    vertices = np.concatenate([pole0[None], rings.reshape(-1, 3), pole1[None]])
    vert_axial = np.concatenate([[-tube.caps[0]], np.repeat(ring_s, m), [axial[-1] + tube.caps[1]]])

    # Faces: fan at each pole, two triangles per quad between consecutive rings.
    ring_ids = 1 + np.arange(n_rings * m).reshape(n_rings, m)
    nxt = np.roll(np.arange(m), -1)
    fan0 = np.stack([np.zeros(m, int), ring_ids[0, nxt], ring_ids[0]], axis=1)
    last = n_rings * m + 1
    fan1 = np.stack([np.full(m, last), ring_ids[-1], ring_ids[-1, nxt]], axis=1)
    q0, q1 = ring_ids[:-1], ring_ids[1:]
    quads = np.concatenate([np.stack([q0, q0[:, nxt], q1], -1).reshape(-1, 3),
                            np.stack([q0[:, nxt], q1[:, nxt], q1], -1).reshape(-1, 3)])
    faces = np.concatenate([fan0, quads, fan1])

    first_body_ring = tube.cap_rings[0] - 1
    knot_station = np.searchsorted(u, np.arange(n_knots))
    knot_rings = {k: ring_ids[first_body_ring + knot_station[k]] for k in range(n_knots)}
    return _TubeMesh(vertices, faces, vert_axial, axial[knot_station], knot_rings)


def _signed_volume(vertices: np.ndarray, faces: np.ndarray) -> float:
    """Volume enclosed by a closed mesh; positive when faces wind counter-clockwise seen from outside."""
    v0, v1, v2 = (vertices[faces[:, i]] for i in range(3))
    return float(np.einsum("ij,ij->", v0, np.cross(v1, v2)) / 6.0)


_MIRROR = np.array([-1.0, 1.0, 1.0])


def _mirror_joint(j: int) -> int:
    right = {**LEFT_TO_RIGHT, **{r: l for l, r in LEFT_TO_RIGHT.items()}}
    return right.get(j, j)


def _surface(p: Proportions) -> tuple[list[_Tube], list[_TubeMesh], np.ndarray]:
    """Tubes, their meshes (right-side mirrors appended after their left tube) and all vertices ``(N, 3)``
    after the height stretch."""
    tubes, meshes = [], []
    for tube in _tubes(p):
        mesh = _sweep(tube)
        tubes.append(tube)
        meshes.append(mesh)
        if tube.mirrored:
            tubes.append(replace(tube, owners=tuple(map(_mirror_joint, tube.owners)),
                                 joint_knots=tuple((_mirror_joint(j), k) for j, k in tube.joint_knots)))
            meshes.append(replace(mesh, vertices=mesh.vertices * _MIRROR, faces=mesh.faces[:, ::-1]))
    vertices = np.concatenate([m.vertices for m in meshes])
    return tubes, meshes, _stretch(vertices, p.height)


def _stretch(points: np.ndarray, height: float) -> np.ndarray:
    """Vertical stretch about the soles."""
    out = points.copy()
    out[..., 1] = SOLE_HEIGHT + (points[..., 1] - SOLE_HEIGHT) * height
    return out
