"""Front/back confusions of a single-image pose estimator, resolved by the way a person walks.

From one image, a body seen from behind and the same body seen from the front, mirrored through the
image plane, give the same picture up to shading. BlazePose, trained on people whose faces show, often
takes a back for a front: it then names the right shoulder "left" (and every other side) and puts
the limbs' depths on the wrong side of the hips. Its visibility does not flag it. On the suite's
faceless people these frames are most of the 2D error (``docs/RESULTS.md``, issue 16).

A reading can also be half right: on close-ups and people cut by the frame's foot, BlazePose sometimes
reads the shoulders from the back and the hips from the front (hips and shoulders 100-180° apart, where a
trunk twists 60° at most). :func:`untwisted` mirrors such a reading's hips and legs onto the shoulders'
side first, so that the reading and its mirror below are each a whole body. The shoulders were the right
half in 24 of the suite's 43 such readings, the hips in 13; which half is mirrored decides only which of
the two whole readings is BlazePose's own, since the labelling chooses between them. Left twisted, the
fit's first orientation follows the shoulders and its smoothness carries the turn to the neighbouring
frames: s09's first track faced 50-98° off over its first six frames, whose readings were within 30°.

Each frame of a track has two readings, BlazePose's and its mirror (sides swapped, depths relative to
the hips negated), and each reading faces a way (:func:`reading_forward`). The labelling of a track
is the cheapest path through them (Viterbi, :func:`facing_flips`):
- people walk forwards: where the whole body is seen and the fit's root moves (camera frame, a
  least-squares line over a few frames), a reading facing against the motion costs, one facing along it
  gains; the motion along the line of sight counts at half (:func:`evidence_speed`), since the fit's
  depth, read from the body's size, wanders while a person stands;
- bodies turn slowly: a reading turned 180° from the previous frame's costs ``turn_cost``, so the
  walk's evidence carries to frames where it says nothing (a track's first frames, a person standing
  or walking across the view), and BlazePose's frame-by-frame flips are undone as a run;
- heads show their faces: where a head's middle is unlike its crown it is a face, where alike the back
  of a head (:mod:`.head_colour`, which also speaks for a person standing still); a reading facing
  the camera gains where the head shows a face and costs where it shows hair (whole bodies only, as
  for the walk: the backend passes the cue for judged frames);
- BlazePose's own reading is kept where nothing else decides (``mirror_cost``).
Judging the reading itself, not the body fitted to all readings, matters: the fit's smoothness blends
flipped and unflipped frames into a slow turn that faces neither way (s09's track starts were 135, 99,
62° off). Frames whose hips are not seen are not linked, and only frames whose hips, knees and ankles
are all seen give evidence: on close-ups (Megamind.avi) the fitted depth wanders, and evidence from them
mirrored 66 of 457 person-frames of real, front-facing people (from whole bodies only: 7).
A person walking backwards would be mirrored wrongly; so would one whose camera-frame motion is the
camera's own (a dolly faster than the walk). Both are rare in the footage the method is for.

Once labelled, a reading still faces only roughly the right way: BlazePose's yaw of a body seen from behind
or obliquely is often 60-85° off. Where the person walks, the walk's direction across the trunk is a
sharper estimate of the facing (8° off on average against the readings' 21° on the suite's first shots),
so :func:`walk_headings` turns each such reading about its trunk by the inverse-variance mean of the two.
Like the labels, it reads the walk from whole bodies only: with the hips alone seen, Megamind.avi's
standing people (waist-up dialogue shots whose fitted depth wanders) had 63 of 423 person-frames turned,
28 of them by more than 20°; from whole bodies, 12 and 9.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from multithumbs.geometry import axis_angle_to_matrix

BLAZEPOSE_MIRROR: tuple[int, ...] = (0, 4, 5, 6, 1, 2, 3, 8, 7, 10, 9, 12, 11, 14, 13, 16, 15, 18, 17, 20, 19, 22,
                                     21, 24, 23, 26, 25, 28, 27, 30, 29, 32, 31)
"""BlazePose's 33 landmarks with left and right exchanged (nose 0; eyes 1-3 / 4-6; ears 7 / 8; mouth
9 / 10; then shoulders, elbows, wrists, pinkies, index fingers, thumbs, hips, knees, ankles, heels and
foot tips in left / right pairs from 11 / 12 to 31 / 32)."""

LOWER_BODY: tuple[int, ...] = tuple(range(23, 33))
"""BlazePose's hips, knees, ankles, heels and foot tips: the half of a twisted reading that is mirrored."""


@dataclass(frozen=True)
class FacingConfig:
    """How a track's readings are labelled front or back (module docstring)."""

    enabled: bool = True
    """Mirror the readings the labelling takes for a back seen as a front."""
    min_speed: float = 0.005
    """Metres per frame (0.12 m/s at 24 fps) the fitted root must move for the walk to say anything."""
    full_speed: float = 0.02
    """Metres per frame at which the walk's evidence has its full weight (it grows linearly up to it)."""
    view_speed_scale: float = 0.5
    """How much the walk's component along the line of sight counts towards ``min_speed`` and ``full_speed``
    (1: as much as the motion across it; :func:`evidence_speed`). The fit's depth comes from the body's size
    in the image and wanders along the view: over the suite's judged frames of people standing still, the
    first fit's root moved along the view at a median 2.1 mm a frame (90th percentile 10.5) and across it at
    0.8 (5.3), and 35 % of them passed ``min_speed`` (s05's person 1, standing side-on, read as walking away
    at 14 mm a frame and mirrored for 19 frames). At 0.5: 19 % of standing frames pass it, and walkers' mean
    weight goes 0.99 to 0.96."""
    turn_cost: float = 4.0
    """Cost of a reading turned 180° from the previous linked frame's (1 - cosine, halved, times this;
    divided by the frames between them), against at most 1 per frame from the walk. At 2 a track's first
    frames, read as a front before the walk or a face says anything, kept their wrong label while the rest
    of the track was mirrored (s01's and s09's first shots, 140-157° off at W-MPJPE's two aligned frames):
    4 takes the suite's nothing-simulated W-MPJPE from 752.7 to 651.7 mm with the same bodies elsewhere;
    8 gave the same W-MPJPE but kept a long wrong run in s05 (MPJPE 101 -> 120 mm). On Megamind.avi's
    front-facing characters, fitted bodies facing away: 12 of 422 person-frames at 2, 17 at 4, 11 at 8."""
    mirror_cost: float = 0.05
    """Cost per frame of the mirror reading: BlazePose's own is kept where nothing else decides."""
    window: int = 8
    """Frames either side of a frame whose fitted roots give its motion."""
    min_hip_visibility: float = 0.5
    """Visibility both hips need for a frame to be labelled (its reading's forward is read across them)."""
    link_shoulders: bool = True
    """Also label frames whose hips are unseen but shoulders seen (``min_hip_visibility``), their facing read
    across the shoulders: the turn cost carries the labels of the track's other frames to them."""
    min_leg_visibility: float = 0.5
    """Visibility both hips and one leg's knee and ankle need, inside the image, for the walk to judge the
    frame (:func:`body_seen`): a walk is read from a body seen to its feet; close-ups (faces and shoulders,
    whose fitted depth wanders) give no evidence. One leg, not both: a person seen side-on hides the far
    one (s08's first track, standing then walking, faced 160° off for 25 frames when both were asked for).
    Inside the image: BlazePose gives ankles below the frame a visibility, and on Megamind.avi's waist-up
    shots one leg "seen" anywhere turned 41 of 422 person-frames away from the camera, against 17."""
    heading: bool = True
    """Also turn each judged reading about its trunk towards the walk (:func:`walk_headings`): BlazePose's
    yaw of a body seen from behind or obliquely is often 60-85° off where the walk is within 30°."""
    walk_sigma_deg: float = 10.0
    """Spread of a walker's facing about the direction of their walk (degrees), at full speed: across the
    trunk, the walk was 8.4° from the true facing on average (median 4.1°, 90th percentile 22.9°) in s01's
    and s03's first shots, where the readings were 20.8° off (17.3°, 39.5°)."""
    reading_sigma_deg: float = 25.0
    """Spread of BlazePose's reading's facing about the body's (degrees), once labelled front or back."""
    max_twist_deg: float = 90.0
    """A reading whose hips and shoulders face further apart than this about the trunk is twisted
    (:func:`untwisted`); a trunk twists 45-60° at most. Over the suite's tracks (3447 person-frames) the
    angle's 95th percentile was 42.6° and its 99th 100.7°; 43 readings passed 90°."""
    face_weight: float = 0.5
    """Weight of the head's colours (:func:`.head_colour.face_evidence`, in [-1, 1]) per frame: a reading
    facing the camera (its forward's depth component -1) where the head shows a face gains this much, one
    facing away costs it. Where the cue speaks it was right in 93 % of the frames of s01, s08 and s09
    (BlazePose's own reading: 68 %)."""


def mirrored(image: np.ndarray, world: np.ndarray, flip: np.ndarray,
             landmarks: tuple[int, ...] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """BlazePose's landmarks with the frames ``flip`` marks replaced by their mirror reading.

    Args:
        image: ``(..., 33, C>=3)`` pixel u, v, relative depth z, then any per-landmark scores.
        world: ``(..., 33, 3)`` metres, origin between the hips, camera-aligned axes.
        flip: ``(...)`` bool.
        landmarks: mirror only these (closed under the exchange of sides, as :data:`LOWER_BODY`); all
            when None.
    Returns:
        ``(image, world)`` copies: in flipped frames the sides are exchanged (positions and scores go with
        the anatomical name), and depth z is negated relative to the hips (world) or to the landmarks'
        own hip mid-point (image).
    """
    image, world = np.array(image, dtype=np.float64), np.array(world, dtype=np.float64)
    flip = np.asarray(flip, bool)
    order, changed = _mirror_order(landmarks)
    swapped_image = image[..., order, :]
    hips_z = 0.5 * (image[..., 23:24, 2] + image[..., 24:25, 2])  # the exchange leaves it alone
    swapped_image[..., 2] = np.where(changed, 2 * hips_z - swapped_image[..., 2], swapped_image[..., 2])
    return (np.where(flip[..., None, None], swapped_image, image),
            np.where(flip[..., None, None], mirror_world(world, landmarks), world))


def mirror_world(world: np.ndarray, landmarks: tuple[int, ...] | None = None) -> np.ndarray:
    """The mirror reading of world landmarks ``(..., 33, 3)`` (hip-centred): sides exchanged, depth negated
    (of ``landmarks`` only, when given)."""
    order, changed = _mirror_order(landmarks)
    mirror = np.asarray(world, dtype=np.float64)[..., order, :]
    mirror[..., changed, 2] *= -1.0
    return mirror


def _mirror_order(landmarks: tuple[int, ...] | None) -> tuple[list[int], np.ndarray]:
    """The landmark order of the mirror of ``landmarks`` (all when None) and the ``(33,)`` mask it changes."""
    index = np.arange(len(BLAZEPOSE_MIRROR))
    changed = np.ones(index.size, bool) if landmarks is None else np.isin(index, landmarks)
    return [BLAZEPOSE_MIRROR[i] if changed[i] else i for i in index], changed


def twisted(world: np.ndarray, max_twist_deg: float) -> np.ndarray:
    """``(...)`` bool: readings ``world (..., 33, 3)`` whose hips and shoulders face more than
    ``max_twist_deg`` apart about the trunk (each half's forward: across it, crossed with the trunk's up)."""
    hips, shoulders = _forward_across(world, HIP_LANDMARKS), _forward_across(world, SHOULDER_LANDMARKS)
    norms = np.linalg.norm(hips, axis=-1) * np.linalg.norm(shoulders, axis=-1)
    return (hips * shoulders).sum(-1) < np.cos(np.radians(max_twist_deg)) * norms


def untwisted(image: np.ndarray, world: np.ndarray, valid: np.ndarray,
              config: FacingConfig = FacingConfig()) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """BlazePose's landmarks ``image (..., 33, C)``, ``world (..., 33, 3)`` with each valid reading whose
    halves face opposite ways (:func:`twisted`) made whole: its hips and legs mirrored onto the shoulders'
    side (module docstring). Returns the two and the ``(...)`` frames changed; none when the labelling is
    off."""
    twist = np.asarray(valid, bool) & twisted(world, config.max_twist_deg) if config.enabled else \
        np.zeros(np.shape(valid), bool)
    image, world = mirrored(image, world, twist, LOWER_BODY)
    return image, world, twist


def body_forward(joints: np.ndarray) -> np.ndarray:
    """Unit forward direction ``(..., 3)`` of SMPL-order joints ``(..., 24, 3)``: across the hips (left
    minus right) crossed with up the spine (neck minus pelvis), which is SMPL's +z at rest."""
    joints = np.asarray(joints, dtype=np.float64)
    forward = np.cross(joints[..., 1, :] - joints[..., 2, :], joints[..., 12, :] - joints[..., 0, :])
    return forward / np.maximum(np.linalg.norm(forward, axis=-1, keepdims=True), 1e-12)


def root_velocity(transl: np.ndarray, valid: np.ndarray, window: int) -> np.ndarray:
    """Per-frame velocity ``(P, T, 3)`` (units per frame): the slope of a least-squares line through the
    valid roots ``transl (P, T, 3)`` within ``window`` frames either side; nan in invalid frames and where
    fewer than 3 valid frames are near."""
    transl, valid = np.asarray(transl, dtype=np.float64), np.asarray(valid, bool)
    velocity = np.full(transl.shape, np.nan)
    num_frames = valid.shape[1]
    for p, t in zip(*np.nonzero(valid)):
        a, b = max(0, t - window), min(num_frames, t + window + 1)
        times = np.arange(a, b)[valid[p, a:b]]
        if times.size < 3:
            continue
        centred = times - times.mean()
        velocity[p, t] = centred @ (transl[p, times] - transl[p, times].mean(0)) / (centred @ centred)
    return velocity


def evidence_speed(velocity: np.ndarray, view: np.ndarray | None, view_scale: float) -> np.ndarray:
    """``(...)`` the speed of ``velocity (..., 3)`` as the walk's evidence counts it: its component along
    ``view (..., 3)`` (unit vectors from the camera to the root) times ``view_scale``, the rest in full; the
    plain speed when ``view`` is None. A monocular fit's depth, read from the body's size, is the noisy part
    of its root (:attr:`FacingConfig.view_speed_scale`)."""
    velocity = np.asarray(velocity, dtype=np.float64)
    if view is None:
        return np.linalg.norm(velocity, axis=-1)
    along = (velocity * view).sum(-1, keepdims=True)
    return np.linalg.norm(velocity - (1.0 - view_scale) * along * view, axis=-1)


def trunk_up(world: np.ndarray) -> np.ndarray:
    """Up the trunk ``(..., 3)`` of BlazePose world landmarks ``(..., 33, 3)``: mid-shoulders minus mid-hips."""
    world = np.asarray(world, dtype=np.float64)
    return 0.5 * (world[..., 11, :] + world[..., 12, :] - world[..., 23, :] - world[..., 24, :])


def _forward_across(world: np.ndarray, pair: tuple[int, int]) -> np.ndarray:
    """``(..., 3)`` across a left / right ``pair`` of BlazePose world landmarks (left minus right) crossed
    with up the trunk (:func:`trunk_up`): the way that pair faces, not normalised."""
    world = np.asarray(world, dtype=np.float64)
    return np.cross(world[..., pair[0], :] - world[..., pair[1], :], trunk_up(world))


def reading_forward(world: np.ndarray) -> np.ndarray:
    """Unit forward ``(..., 3)`` of BlazePose world landmarks ``(..., 33, 3)``: across the hips (left minus
    right) crossed with up the trunk (:func:`trunk_up`), as :func:`body_forward` for SMPL."""
    forward = _forward_across(world, HIP_LANDMARKS)
    return forward / np.maximum(np.linalg.norm(forward, axis=-1, keepdims=True), 1e-12)


def shoulders_forward(world: np.ndarray) -> np.ndarray:
    """:func:`reading_forward` read across the shoulders, for frames whose hips are unseen."""
    forward = _forward_across(world, SHOULDER_LANDMARKS)
    return forward / np.maximum(np.linalg.norm(forward, axis=-1, keepdims=True), 1e-12)


def facing_flips(world: np.ndarray, velocity: np.ndarray, linked: np.ndarray, judged: np.ndarray,
                 config: FacingConfig = FacingConfig(), face: np.ndarray | None = None,
                 hips_seen: np.ndarray | None = None, view: np.ndarray | None = None) -> np.ndarray:
    """``(P, T)`` bool: the frames whose reading the labelling mirrors (module docstring).

    Args:
        world: ``(P, T, 33, 3)`` BlazePose's world landmarks as read.
        velocity: ``(P, T, 3)`` the fitted roots' motion per frame (:func:`root_velocity`); nan where unknown.
        linked: ``(P, T)`` bool, the frames labelled (hips seen); the others keep their reading.
        judged: ``(P, T)`` bool, the frames whose walk gives evidence (a subset of ``linked`` counts).
        face: ``(P, T)`` in [-1, 1], optional: +1 where the head shows a face, -1 its back, 0 unknown
            (:func:`.head_colour.face_evidence`).
        hips_seen: ``(P, T)`` bool, optional: frames whose facing is read across the hips; the others'
            across the shoulders (:func:`shoulders_forward`). All across the hips when None.
        view: ``(P, T, 3)`` unit vectors from the camera to each root, optional: the walk's component along
            them counts ``view_speed_scale`` towards its weight (:func:`evidence_speed`).
    """
    world, velocity = np.asarray(world, dtype=np.float64), np.asarray(velocity, dtype=np.float64)
    linked = np.asarray(linked, bool)
    flips = np.zeros(linked.shape, bool)
    if not config.enabled:
        return flips
    # (P, T, 2, 3): the forward of each frame's two readings, BlazePose's then the mirror.
    mirror = mirror_world(world)
    forward = np.stack([reading_forward(world), reading_forward(mirror)], axis=-2)
    if hips_seen is not None:
        across_shoulders = np.stack([shoulders_forward(world), shoulders_forward(mirror)], axis=-2)
        forward = np.where(np.asarray(hips_seen, bool)[..., None, None], forward, across_shoulders)
    known = np.isfinite(velocity).all(-1) & linked & np.asarray(judged, bool)
    motion = np.where(known[..., None], velocity, 0.0)
    speed = evidence_speed(motion, view, config.view_speed_scale)
    weight = np.where(speed > config.min_speed, np.minimum(speed / config.full_speed, 1.0), 0.0)
    direction = motion / np.maximum(np.linalg.norm(motion, axis=-1), 1e-12)[..., None]
    unary = -weight[..., None] * np.einsum("ptsk,ptk->pts", forward, direction) + np.array([0.0, config.mirror_cost])
    if face is not None:
        # The camera looks along +z: a reading facing it has a negative forward depth.
        unary = unary + config.face_weight * np.asarray(face, dtype=np.float64)[..., None] * forward[..., 2]
    for p in range(linked.shape[0]):
        frames = np.flatnonzero(linked[p])
        if frames.size:
            flips[p, frames] = _cheapest_labels(unary[p, frames], forward[p, frames], np.diff(frames), config.turn_cost)
    return flips


def _cheapest_labels(unary: np.ndarray, forward: np.ndarray, gaps: np.ndarray, turn_cost: float) -> np.ndarray:
    """Viterbi over two states per frame: ``unary (n, 2)`` costs, ``forward (n, 2, 3)`` the readings' facing,
    ``gaps (n-1)`` frames between neighbours. Returns ``(n,)`` bool, True where the mirror is cheapest."""
    n = unary.shape[0]
    cost, back = unary[0].copy(), np.zeros((n, 2), np.int64)
    for i in range(1, n):
        turn = turn_cost / gaps[i - 1] * 0.5 * (1.0 - forward[i - 1] @ forward[i].T)   # (previous, current)
        total = cost[:, None] + turn
        back[i] = total.argmin(0)
        cost = total.min(0) + unary[i]
    labels = np.zeros(n, np.int64)
    labels[-1] = cost.argmin()
    for i in range(n - 1, 0, -1):
        labels[i - 1] = back[i, labels[i]]
    return labels.astype(bool)


def walk_headings(world: np.ndarray, velocity: np.ndarray, judged: np.ndarray,
                  config: FacingConfig = FacingConfig(), view: np.ndarray | None = None
                  ) -> tuple[np.ndarray, np.ndarray]:
    """BlazePose's world landmarks turned about their trunk towards the walk, where it is known.

    People walk forwards, so where the walk is read (``judged`` frames moving faster than ``min_speed``)
    the facing has two estimates: the reading's own (spread ``reading_sigma_deg``) and the walk's
    direction in the plane across the trunk (``walk_sigma_deg`` at ``full_speed``, wider below it). Each
    such reading is turned by their inverse-variance mean: the angle from its forward to the walk's,
    times ``w / (w + r)`` with ``w, r`` the two precisions. A reading facing more than 90° from the walk
    is left alone (the labelling kept it; :func:`facing_flips`), as is every frame the walk says nothing of.

    Args:
        world: ``(P, T, 33, 3)`` hip-centred world landmarks (after :func:`mirrored`).
        velocity: ``(P, T, 3)`` the roots' motion per frame (:func:`root_velocity`); nan where unknown.
        judged: ``(P, T)`` bool, frames whose walk gives evidence.
        view: ``(P, T, 3)`` unit vectors from the camera to each root, optional (:func:`evidence_speed`).
    Returns:
        the turned ``(P, T, 33, 3)`` landmarks and the ``(P, T)`` turns (radians about the trunk's up,
        0 where untouched).
    """
    world, velocity = np.asarray(world, dtype=np.float64), np.asarray(velocity, dtype=np.float64)
    turn = np.zeros(world.shape[:2])
    if not (config.enabled and config.heading):
        return world.copy(), turn
    up = trunk_up(world)
    up = up / np.maximum(np.linalg.norm(up, axis=-1, keepdims=True), 1e-12)
    forward = reading_forward(world)
    motion = np.where(np.isfinite(velocity), velocity, 0.0)
    across = motion - (motion * up).sum(-1, keepdims=True) * up  # the walk in the plane across the trunk
    speed = evidence_speed(across, view, config.view_speed_scale)
    direction = across / np.maximum(np.linalg.norm(across, axis=-1), 1e-12)[..., None]
    angle = np.arctan2((np.cross(forward, direction) * up).sum(-1), (forward * direction).sum(-1))
    walk_sigma = np.radians(config.walk_sigma_deg) * config.full_speed / np.clip(speed, 1e-12, config.full_speed)
    walk_precision, reading_precision = 1.0 / walk_sigma ** 2, 1.0 / np.radians(config.reading_sigma_deg) ** 2
    use = (np.asarray(judged, bool) & np.isfinite(velocity).all(-1) & (speed > config.min_speed)
           & (np.abs(angle) <= 0.5 * np.pi))
    turn = np.where(use, angle * walk_precision / (walk_precision + reading_precision), 0.0)
    # A rigid turn about the trunk through the mid-hip; untouched frames keep their bytes.
    centre = 0.5 * (world[..., 23:24, :] + world[..., 24:25, :])
    rotation = axis_angle_to_matrix(up * turn[..., None])
    turned = centre + np.einsum("ptij,ptkj->ptki", rotation, world - centre)
    return np.where((turn != 0)[..., None, None], turned, world), turn


HIP_LANDMARKS: tuple[int, ...] = (23, 24)
"""BlazePose's hips."""
SHOULDER_LANDMARKS: tuple[int, ...] = (11, 12)
"""BlazePose's shoulders."""
LEG_LANDMARKS: tuple[tuple[int, ...], ...] = ((25, 27), (26, 28))
"""BlazePose's left and right knee and ankle."""


def landmarks_seen(image: np.ndarray, min_visibility: float, landmarks: tuple[int, ...],
                   image_size: tuple[int, int] | None = None) -> np.ndarray:
    """``(...)`` bool: every one of ``landmarks`` of BlazePose's landmarks ``image (..., 33, 5)`` has
    visibility (column 3) at least ``min_visibility`` and, when ``image_size (H, W)`` is given, lies inside
    the image (BlazePose gives landmarks beyond the frame's edge a visibility too)."""
    image = np.asarray(image)[..., list(landmarks), :]
    seen = image[..., 3].min(-1) >= min_visibility
    if image_size is not None:
        h, w = image_size
        seen &= ((image[..., 0] >= 0) & (image[..., 0] < w) & (image[..., 1] >= 0) & (image[..., 1] < h)).all(-1)
    return seen


def body_seen(image: np.ndarray, min_visibility: float, image_size: tuple[int, int] | None = None) -> np.ndarray:
    """``(...)`` bool: both hips and one leg's knee and ankle seen (:func:`landmarks_seen`), a body in view
    to its feet: the frames whose walk the labelling and the headings read (``FacingConfig.min_leg_visibility``)."""
    legs = [landmarks_seen(image, min_visibility, leg, image_size) for leg in LEG_LANDMARKS]
    return landmarks_seen(image, min_visibility, HIP_LANDMARKS, image_size) & (legs[0] | legs[1])


__all__ = ["HIP_LANDMARKS", "SHOULDER_LANDMARKS", "LEG_LANDMARKS", "LOWER_BODY", "landmarks_seen", "body_seen",
           "trunk_up", "reading_forward", "shoulders_forward", "BLAZEPOSE_MIRROR", "FacingConfig", "mirrored",
           "mirror_world", "twisted", "untwisted", "body_forward", "root_velocity", "evidence_speed", "facing_flips",
           "walk_headings"]
