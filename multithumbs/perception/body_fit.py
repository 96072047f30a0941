"""SMPL bodies fitted to a tracked person's keypoints: 2D pixels and metric 3D joints, per frame.

For landmark detectors that give no SMPL parameters (BlazePose: 2D landmarks and "world landmarks",
metric 3D relative to the mid-hip in camera-aligned axes), mapped onto SMPL's joints with confidence 0
where there is no counterpart. :func:`fit_bodies` fits all people and frames in one batched optimisation.

A closed-form start puts the optimiser in the right basin:

* orientation: Kabsch of the rest pose's hips and shoulders onto the 3D ones, else onto the 2D ones
  lifted onto a fronto-parallel plane (facing the camera or away, and the roll); a frame with fewer than
  three of them, or collinear ones, takes its person's nearest frame that has them;
* position, weak perspective: the keypoints against the 3D joints' offsets from the mid-hip (the rotated
  rest torso where those are absent) give the mid-hip's image and depth, robustly;
* betas from the median 3D bone lengths; hips, knees, shoulders and elbows bent onto the 3D bones (2D
  ones lifted onto the fronto-parallel plane where 3D is absent), the other joints at rest.

L-BFGS then minimises over orientation (an increment on the start: no axis-angle wrap near the half turn
of an upright body facing the camera), pelvis position, body pose and betas

    (1/N) [ Σ_frames ( w2d Σ_j c_j ρ(‖π(J_j) − u_j‖) + w3d Σ_j c'_j ‖(J_j − J_mid) − X_j‖² + wθ ‖θ‖² )
            + ws Σ_windows Σ_j ‖J_{t−1} − 2J_t + J_{t+1}‖² + wβ Σ_people ‖β‖² ]

over the ``N`` valid frames: ``J`` camera-frame joints (:meth:`multithumbs.body.model.BodyModel.joints`,
no mesh), ``π`` the projection through ``K``, ``u, c`` keypoints and confidences, ``X, c'`` 3D joints
relative to the mid-hip ``J_mid`` and confidences, ``ρ`` Geman-McClure. A window is three consecutive
valid frames. Invalid frames have no term; their parameters are copied from the nearest valid frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from multithumbs.conventions import NUM_BETAS, NUM_BODY_JOINTS, NUM_JOINTS
from multithumbs.determinism import THREADS, fix_threads
from multithumbs.errors import InputError
from multithumbs.geometry import axis_angle_to_matrix, matrix_to_axis_angle, umeyama
from multithumbs.types import check_array

TORSO = (1, 2, 16, 17)
"""SMPL hips and shoulders: the joints the orientation is initialised from."""

BONES = ((0, 1), (0, 2), (1, 2), (1, 4), (2, 5), (4, 7), (5, 8), (16, 17), (16, 18), (17, 19), (18, 20), (19, 21),
         (0, 16), (0, 17))
"""Joint pairs whose distance the pose leaves (nearly) alone, so it measures the shape: parent and child,
siblings, and across collars and spine (rigid while those joints, which nothing observes, stay near rest)."""

LIMBS = ((0, 1, 4), (0, 2, 5), (1, 4, 7), (2, 5, 8), (13, 16, 18), (14, 17, 19), (16, 18, 20), (17, 19, 21))
"""``(parent, joint, child)``, parents first: the rotation of ``joint`` turns its rest bone to ``child``
onto the detected one (hips, knees, shoulders, elbows)."""

FACING_CAMERA = np.diag([1.0, -1.0, -1.0])
"""Body-to-camera rotation of an upright body facing the camera (body +y up -> camera -y, front +z -> -z)."""

DEFAULT_DEPTH = 4.0
"""Depth (m) a person with no usable frame at all is placed at."""


@dataclass(frozen=True)
class BodyFitConfig:
    """Settings of :func:`fit_bodies`. Weights are a Gaussian MAP estimate's: ``1 / σ²`` of each residual's
    expected error (terms are sums over joints and frames divided by the number of valid frames).

    Attributes:
        iterations: L-BFGS iterations (at most 1.25 objective evaluations each); 0 returns the closed-form
            start. Synthetic 4 people x 120 frames (the test scene): MPJPE 114 mm from the start, 62 mm after
            100, 43 after 200, 33 after 300 (~20 ms per frame on one thread), 30 after 1000.
        learning_rate: L-BFGS step scale (1: the quasi-Newton step, which the strong-Wolfe line search adjusts).
        w_keypoints2d: weight of a full-confidence keypoint's squared pixel residual (px⁻²): good to ~3 px.
        w_joints3d: weight of a full-confidence 3D joint's squared error (m⁻²): good to ~5 cm.
        w_pose_prior: weight of ``‖body_pose‖²`` per frame (rad⁻²): joints rarely bend beyond ~1 rad per
            component from rest, and the unobserved ones (spine, neck, head, collars, feet, hands) stay near it.
        w_betas: weight of ``‖β‖²`` per person: SMPL's shape space has unit variance.
        w_smooth: weight of every joint's squared second difference over consecutive valid frames (m⁻²):
            joints accelerate by ~2 cm per frame² at 30 fps.
        robust_sigma_px: Geman-McClure scale ``σ`` (px), ``ρ(r) = σ² r² / (σ² + r²)``: quadratic below it,
            saturating at ``σ²`` above, so a mis-detected keypoint pulls with bounded force.
        threads: torch intra-op threads, set for good with :func:`multithumbs.determinism.fix_threads` (the
            result's bits depend on the count; one thread is as fast here, and two ran up to 30x slower
            while other processes kept both cores busy); 0 leaves torch's setting alone.
    """

    iterations: int = 300
    learning_rate: float = 1.0
    w_keypoints2d: float = 1.0 / 9.0
    w_joints3d: float = 400.0
    w_pose_prior: float = 1.0
    w_betas: float = 1.0
    w_smooth: float = 2500.0
    robust_sigma_px: float = 20.0
    threads: int = THREADS


@dataclass(frozen=True)
class FittedBodies:
    """SMPL parameters of every person and frame in the camera frame (:mod:`multithumbs.conventions`).

    Invalid frames hold the values of their person's nearest valid frame (ties: the earlier one); a
    person with no valid frame gets an upright body facing the camera at ``DEFAULT_DEPTH``, zero pose.

    Attributes:
        global_orient: ``(P, T, 3)`` axis-angle, body to camera.
        body_pose: ``(P, T, 23, 3)`` axis-angle.
        betas: ``(P, 10)``.
        transl: ``(P, T, 3)`` metres, added to every vertex (smplx).
        reprojection_px: ``(P, T)`` confidence-weighted mean pixel distance of the fitted joints to the 2D
            keypoints; nan in invalid frames and frames without a confident keypoint.
    """

    global_orient: np.ndarray
    body_pose: np.ndarray
    betas: np.ndarray
    transl: np.ndarray
    reprojection_px: np.ndarray


def fit_bodies(keypoints2d, joints3d, valid, K, body=None, config: BodyFitConfig = BodyFitConfig()) -> FittedBodies:
    """Fit SMPL to every person's per-frame detections (module docstring). Deterministic for a thread count.

    Args:
        keypoints2d: ``(P, T, 24, 3)`` pixel ``u, v`` and confidence in [0, 1], SMPL joint order;
            confidence 0 for joints the detector has no counterpart for.
        joints3d: ``(P, T, 24, 4)`` ``x, y, z`` metres in camera-aligned axes (+x right, +y down, +z away
            from the camera) relative to the mid-point of SMPL's hips (joints 1 and 2), and a confidence
            in [0, 1]; 0 where unmapped or absent. Their scale sets the depth: a skeleton 10% small puts
            the body 10% near.
        valid: ``(P, T)`` bool, the person was detected in that frame. Other frames may hold anything.
        K: ``(3, 3)`` intrinsics.
        body: a :class:`multithumbs.body.model.BodyModel`; default :func:`~multithumbs.body.model.load_body_model`.
        config: the settings.
    Raises:
        InputError: naming the argument, for wrong shapes or dtypes, non-finite values in valid frames,
            confidences outside [0, 1] or a ``K`` that is not a finite pinhole matrix.
    """
    kp, x3, valid, K = _checked(keypoints2d, joints3d, valid, K)
    if body is None:
        from multithumbs.body.model import load_body_model  # loads smplx: only when needed
        body = load_body_model()
    p_count, t_count = valid.shape
    if p_count * t_count == 0:
        return FittedBodies(np.zeros((p_count, t_count, 3)), np.zeros((p_count, t_count, NUM_BODY_JOINTS, 3)),
                            np.zeros((p_count, NUM_BETAS)), np.zeros((p_count, t_count, 3)),
                            np.full((p_count, t_count), np.nan))
    if config.threads > 0:  # one count, one rounding (multithumbs.determinism)
        fix_threads(config.threads)
    with torch.no_grad():
        rest = body.rest_joints(np.zeros(NUM_BETAS)).double().numpy()                      # (24, 3)
        shape_dirs = body.rest_joints(np.eye(NUM_BETAS)).double().numpy() - rest            # (10, 24, 3)
    rotation, pelvis = _initialise(kp, x3, valid, K, rest, config.robust_sigma_px)
    betas = _initial_betas(x3, rest, shape_dirs, config)
    midhip = pelvis - rotation @ (rest[0] - 0.5 * (rest[1] + rest[2]))
    pose = _limb_pose(_lifted(kp, x3, K, midhip), rotation, rest)
    return _optimise(kp, x3, valid, K, body, config, (rotation, pelvis, pose, betas))


def _checked(keypoints2d, joints3d, valid, K):
    """The inputs as float64 / bool copies, checked; invalid frames zeroed (confidence 0: they drop out)."""
    sizes: dict[str, int] = {}
    kp = check_array("fit_bodies", "keypoints2d", keypoints2d, ("P", "T", NUM_JOINTS, 3), sizes).astype(np.float64)
    x3 = check_array("fit_bodies", "joints3d", joints3d, ("P", "T", NUM_JOINTS, 4), sizes).astype(np.float64)
    valid = check_array("fit_bodies", "valid", valid, ("P", "T"), sizes, "b").copy()
    K = check_array("fit_bodies", "K", K, (3, 3), sizes).astype(np.float64)
    if not np.isfinite(K).all() or not (K[0, 0] > 0 and K[1, 1] > 0) or not np.allclose(K[2], [0, 0, 1]):
        raise InputError(f"fit_bodies.K: expected finite pinhole intrinsics (positive focal lengths, last row "
                         f"0 0 1), got {K.tolist()}")
    for name, array in (("keypoints2d", kp), ("joints3d", x3)):
        if not np.isfinite(array[valid]).all():
            raise InputError(f"fit_bodies.{name}: non-finite values in valid frames")
        array[~valid] = 0.0
        confidence = array[..., -1]
        if confidence.min(initial=0.0) < 0 or confidence.max(initial=0.0) > 1:
            raise InputError(f"fit_bodies.{name}: confidences must lie in [0, 1], got values in "
                             f"[{confidence.min():.3g}, {confidence.max():.3g}]")
    return kp, x3, valid, K


def _initialise(kp, x3, valid, K, rest, sigma_px: float):
    """Closed-form ``(P, T, 3, 3)`` body-to-camera rotations and ``(P, T, 3)`` pelvis positions (module docstring).

    ``kp (P, T, 24, 3)`` and ``x3 (P, T, 24, 4)`` with confidences zeroed in invalid frames, ``rest (24, 3)``
    the rest joints. Every output is finite; frames without what a step needs hold the nearest frame's result.
    """
    rest_rel = rest - 0.5 * (rest[1] + rest[2])                                             # mid-hip relative
    # Normalised image coordinates: rays through the keypoints at unit depth.
    normalised = (kp[..., :2] - K[:2, 2]) / np.diag(K)[:2]
    torso = list(TORSO)
    have3d = (x3[..., torso, 3] > 0).sum(-1) >= 3                                          # (P, T)
    # Kabsch target: the 3D torso where there is one, else the 2D torso lifted onto the plane z = 0
    # (rotation only, so the plane's scale, 1 / depth, does not matter).
    lifted = np.concatenate([normalised[..., torso, :], np.zeros(kp.shape[:2] + (len(torso), 1))], -1)
    target = np.where(have3d[..., None, None], x3[..., torso, :3], lifted)
    weight = np.where(have3d[..., None], x3[..., torso, 3], kp[..., torso, 2])
    total = np.maximum(weight.sum(-1), 1e-12)[..., None, None]
    centred = target - (weight[..., None] * target).sum(-2, keepdims=True) / total
    principal = np.linalg.eigvalsh(np.einsum("...n,...ni,...nj->...ij", weight, centred, centred))  # ascending
    # Three points that are not collinear: the second principal spread at least 1% of the first.
    oriented = (valid & ((weight > 0).sum(-1) >= 3) & (principal[..., 2] > 0)
                & (principal[..., 1] > 1e-2 * principal[..., 2]))
    source = np.broadcast_to(rest_rel[torso], target.shape)
    rotation = umeyama(source, target, np.where(oriented[..., None], weight, 1.0), with_scale=False).rotation.numpy()
    rotation = _hold(np.where(oriented[..., None, None], rotation, FACING_CAMERA), oriented)

    # Depth, weak perspective about the mid-hip m (c = m_xy / m_z its image): a joint at offset o images
    # at c + (o_xy - c o_z) / m_z to first order. s = 1 / m_z is the ratio of the keypoints' spread to the
    # offsets' (a regression slope would shrink with any misalignment of a 2D-only start) and c follows
    # from the means; reweighted as Geman-McClure does, since a few mis-detected keypoints would otherwise
    # bias every depth. Offsets from the 3D joints where detected, else from the rotated rest torso.
    offset = np.where(x3[..., 3:] > 0, x3[..., :3], np.einsum("ptij,nj->ptni", rotation, rest_rel))
    base = kp[..., 2] * np.where(x3[..., 3] > 0, 1.0, np.isin(np.arange(NUM_JOINTS), [0, *torso]))
    weight, centre, scale = base, np.zeros(kp.shape[:2] + (1, 2)), np.zeros(kp.shape[:2] + (1, 1))
    for _ in range(4):
        lateral = offset[..., :2] - centre * offset[..., 2:]
        total = np.maximum(weight.sum(-1), 1e-12)[..., None, None]
        mean_2d = (weight[..., None] * normalised).sum(-2, keepdims=True) / total
        mean_3d = (weight[..., None] * lateral).sum(-2, keepdims=True) / total
        spread = (weight * ((lateral - mean_3d) ** 2).sum(-1)).sum(-1)[..., None, None]
        scale = np.sqrt((weight * ((normalised - mean_2d) ** 2).sum(-1)).sum(-1)[..., None, None]
                        / np.maximum(spread, 1e-12))
        centre = mean_2d - scale * mean_3d
        r2 = (((normalised - centre - scale * lateral) * np.diag(K)[:2]) ** 2).sum(-1)
        weight = base * (sigma_px ** 2 / (sigma_px ** 2 + r2)) ** 2
    scale = scale[..., 0, 0]
    placed = valid & ((base > 0).sum(-1) >= 2) & (spread > 1e-6 * total)[..., 0, 0] & (scale > 1e-3)
    midhip = np.concatenate([centre[..., 0, :], np.ones(scale.shape + (1,))], -1)
    midhip = midhip / np.where(placed, scale, 1.0)[..., None]
    pelvis = midhip + np.einsum("ptij,j->pti", rotation, rest_rel[0])
    pelvis = _hold(np.where(placed[..., None], pelvis, [0.0, 0.0, DEFAULT_DEPTH]), placed)
    return rotation, pelvis


def _initial_betas(x3, rest, shape_dirs, config: BodyFitConfig) -> np.ndarray:
    """``(P, 10)`` betas whose rest-pose bone lengths (``BONES``) match the 3D joints' median lengths.

    Bone lengths are linear in the betas to first order (joints are linear in them), so this is one
    regularised least-squares solve per person, weighed like the objective (each frame's length residual
    as a 3D residual, the betas prior once). Without the shape fixed first the optimiser trades it against
    the depth (a bigger body further away projects the same) over many iterations.
    """
    a, b = np.array(BONES).T
    rest_bone = rest[b] - rest[a]                                                            # (B, 3)
    length0 = np.linalg.norm(rest_bone, axis=-1)
    jacobian = np.einsum("bc,kbc->bk", rest_bone / length0[:, None], shape_dirs[:, b] - shape_dirs[:, a])
    both = x3[..., a, 3] * x3[..., b, 3]                                                     # (P, T, B)
    lengths = np.linalg.norm(x3[..., b, :3] - x3[..., a, :3], axis=-1)
    median = np.array([[np.median(lengths[p, both[p, :, k] > 0, k]) if (both[p, :, k] > 0).any() else 0.0
                        for k in range(len(BONES))] for p in range(len(x3))]).reshape(len(x3), len(BONES))
    weight = config.w_joints3d * both.sum(1)                                                 # (P, B)
    normal = np.einsum("pb,bk,bl->pkl", weight, jacobian, jacobian) + config.w_betas * np.eye(NUM_BETAS)
    return np.linalg.solve(normal, np.einsum("pb,bk,pb->pk", weight, jacobian, median - length0)[..., None])[..., 0]


def _lifted(kp, x3, K, midhip) -> np.ndarray:
    """``x3 (P, T, 24, 4)`` with joints that have no 3D position but a 2D keypoint lifted onto the
    fronto-parallel plane through the initial mid-hip ``midhip (P, T, 3)``, relative to it: limbs bent in the
    image plane fit the 2D keypoints far better than the rest pose's outstretched arms."""
    normalised = (kp[..., :2] - K[:2, 2]) / np.diag(K)[:2]
    plane = normalised * midhip[..., None, 2:] - midhip[..., None, :2]
    lifted = np.concatenate([plane, np.zeros_like(plane[..., :1]), kp[..., 2:]], -1)
    return np.where((x3[..., 3:] == 0) & (kp[..., 2:] > 0), lifted, x3)


def _limb_pose(x3, rotation, rest) -> np.ndarray:
    """``(P, T, 23, 3)`` body pose bending the rest pose's limbs onto the detected 3D bones (``LIMBS``).

    Each joint gets the smallest rotation (no twist) taking its rest bone onto the detected bone seen from
    its parent's frame (``rotation (P, T, 3, 3)`` for the pelvis, and for the collars, whose spine stays
    at rest); joints without both 3D ends detected stay at rest. Without this the optimiser first shrinks
    the body to bring T-posed limbs nearer their joints, and takes many iterations to grow it back.
    """
    pose = np.zeros(x3.shape[:2] + (NUM_BODY_JOINTS, 3))
    frame = {0: rotation, 13: rotation, 14: rotation}                                        # global rotations
    for parent, joint, child in LIMBS:
        seen = (x3[..., joint, 3] > 0) & (x3[..., child, 3] > 0)
        target = np.einsum("ptji,ptj->pti", frame[parent], x3[..., child, :3] - x3[..., joint, :3])
        rotvec = np.where(seen[..., None], _smallest_rotation(rest[child] - rest[joint], target), 0.0)
        pose[..., joint - 1, :] = rotvec
        frame[joint] = frame[parent] @ axis_angle_to_matrix(rotvec)
    return pose


def _smallest_rotation(source: np.ndarray, target: np.ndarray) -> np.ndarray:
    """``(..., 3)`` axis-angle of the smallest rotation turning direction ``source (..., 3)`` onto ``target``;
    zero where either is zero or they are opposite (no unique axis: left to the optimiser)."""
    cross = np.cross(source, target)
    sine, cosine = np.linalg.norm(cross, axis=-1), (source * target).sum(-1)
    unique = sine > 1e-9 * np.linalg.norm(source, axis=-1) * np.linalg.norm(target, axis=-1)
    return np.where(unique[..., None], cross / np.where(unique, sine, 1.0)[..., None]
                    * np.arctan2(sine, cosine)[..., None], 0.0)


def _hold(values: np.ndarray, known: np.ndarray) -> np.ndarray:
    """``values (P, T, ...)`` with every frame not ``known (P, T)`` replaced by its person's nearest known
    frame (ties: the earlier); a person with no known frame keeps its values."""
    out, t = values.copy(), np.arange(known.shape[1])
    for p in np.flatnonzero(known.any(axis=1) & ~known.all(axis=1)):
        frames = np.flatnonzero(known[p])
        after = frames[np.minimum(np.searchsorted(frames, t), frames.size - 1)]
        before = frames[np.maximum(np.searchsorted(frames, t, side="right") - 1, 0)]
        out[p] = values[p, np.where(np.abs(before - t) <= np.abs(after - t), before, after)]
    return out


def _optimise(kp, x3, valid, K, body, config: BodyFitConfig, start) -> FittedBodies:
    """Minimise the objective (module docstring) from ``start`` = (rotation, pelvis, body pose, betas)."""
    # The model's dtype (float32 for the shared model): its joints come out in it whatever the parameters'
    # precision, and float32 resolves microns at 10 m. CPU ops are deterministic at a fixed thread count.
    dtype = body.dtype
    as_t = lambda a: torch.as_tensor(np.asarray(a), dtype=dtype)  # noqa: E731
    p_count, t_count = valid.shape
    frames = max(int(valid.sum()), 1)
    rotation0 = as_t(start[0])
    increment = torch.zeros(p_count, t_count, 3, dtype=dtype, requires_grad=True)
    pelvis, body_pose, betas = (as_t(a).clone().requires_grad_(True) for a in start[1:])
    no_orient = torch.zeros(p_count, t_count, 3, dtype=dtype)

    # Every constant weight folded with its mask and 1/N, so the loop runs few ops.
    uv, w2d = as_t(kp[..., :2]), as_t(config.w_keypoints2d * kp[..., 2] / frames)
    xyz, w3d = as_t(x3[..., :3]), as_t(config.w_joints3d * x3[..., 3] / frames)[..., None]
    w_pose = as_t(config.w_pose_prior * valid / frames)[..., None, None]
    windows = valid[:, :-2] & valid[:, 1:-1] & valid[:, 2:]
    w_smooth = as_t(config.w_smooth * windows / frames)[..., None, None]
    w_betas = config.w_betas / frames
    sigma2 = config.robust_sigma_px ** 2
    KT = as_t(K.T)

    def camera_joints():
        """``(P, T, 24, 3)`` joints and ``(P, T, 3, 3)`` body-to-camera rotations of the parameters."""
        local = body.joints(no_orient, body_pose, betas)                                    # pelvis at rest
        R = rotation0 @ axis_angle_to_matrix(increment)
        return (local - local[..., :1, :]) @ R.transpose(-1, -2) + pelvis[..., None, :], R

    def pixel_residual2(joints):
        h = joints @ KT
        return ((h[..., :2] / h[..., 2:].clamp(min=1e-6) - uv) ** 2).sum(-1)               # (P, T, 24)

    def objective():
        joints, _ = camera_joints()
        r2 = pixel_residual2(joints)
        loss = (w2d * (sigma2 * r2 / (sigma2 + r2))).sum()
        relative = joints - 0.5 * (joints[..., 1:2, :] + joints[..., 2:3, :])
        loss = loss + (w3d * (relative - xyz) ** 2).sum() + (w_pose * body_pose ** 2).sum()
        acceleration = joints[:, :-2] - 2 * joints[:, 1:-1] + joints[:, 2:]
        return loss + (w_smooth * acceleration ** 2).sum() + w_betas * (betas ** 2).sum()

    # L-BFGS, not Adam: the smoothness couples frames through the weakly observed depth, which a
    # diagonal method crawls along (synthetic 4 x 120 frames, 200 steps: Adam 53 mm MPJPE, L-BFGS 40 mm).
    if config.iterations > 0:
        opt = torch.optim.LBFGS([increment, pelvis, body_pose, betas], lr=config.learning_rate,
                                max_iter=config.iterations, history_size=20, line_search_fn="strong_wolfe")

        def closure():
            opt.zero_grad(set_to_none=True)
            loss = objective()
            loss.backward()
            return loss

        opt.step(closure)
    with torch.no_grad():
        joints, R = camera_joints()
        residual = pixel_residual2(joints).sqrt().double().numpy()
        transl = (pelvis - body.rest_joints(betas)[:, None, 0, :]).double().numpy()
        orient = matrix_to_axis_angle(R.double()).numpy()
        pose, shape = body_pose.double().numpy(), betas.double().numpy()
    confidence = kp[..., 2]
    seen = valid & (confidence.sum(-1) > 0)
    reprojection = np.where(seen, (confidence * residual).sum(-1) / np.maximum(confidence.sum(-1), 1e-12), np.nan)
    orient[~valid.any(axis=1)] = matrix_to_axis_angle(FACING_CAMERA)
    return FittedBodies(_hold(orient, valid), _hold(pose, valid), shape, _hold(transl, valid), reprojection)


__all__ = ["BodyFitConfig", "FittedBodies", "fit_bodies"]
