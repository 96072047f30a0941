"""Scale and three-stage alignment of boundary meshes to a shared space (paper §3.1–3.2, Algorithm 1).

At a cut, the people of the last frame before it (index 0) and the first frame after it (index 1)
are placed in the cut's shared space:

1. scale: the space is brought to the meshes' metric scale (:mod:`multithumbs.method.scale`);
2. stage 1: each root starts at the scene point under its 2D root keypoint;
3. stage 2: roots (pelvis position Γ, orientation Φ) are refined under the 2D reprojection loss;
4. stage 3: roots and both boundary cameras are refined under 2D + silhouette + depth losses.

Before the stages, with camera refinement on, the second boundary camera is registered to the first by
the two frames' static scenes (:mod:`multithumbs.method.views`; below).

All people and both frames are one batched tensor program. Each body's pose and shape stay fixed
during alignment, so it is posed once (in its own pelvis-centred frame) before the loop.

Loss normalisation (the paper gives weights, not units): 2D residuals are in units of half the image's
larger side, the silhouette loss is the distance (same units) from a projected vertex to the person's
mask, the depth loss is the squared 3D distance (m²) between a camera-facing vertex inside the mask and
the scene point at its pixel. Each is a mean, so the weights do not depend on vertex or joint counts.
Silhouette distances treat pixels covered by other people as unknown (distance 0), so a limb hidden
behind someone else is not pulled out from behind them.

Cameras and their points: a point observed in one boundary frame only was unprojected from that frame's
depth with that frame's camera (VGGT's depth head and our default adapter, the two-view backend's dense
depth, the simulation), so a camera error carries its points with it, and the people's losses, all
relative to that camera, cannot see it: the paper's stage 3 camera refinement then has nothing to fix
(standard suite: no_cam 153.6 mm against full 154.3 before the registration). What does see it is the
disagreement of the two frames' static scenes, which :func:`multithumbs.method.views.register_views`
removes before the stages (full 154.3 -> 118.9 mm; docs/RESULTS.md). In stage 3 such points move with
their camera (``points_follow_cameras``), so refining a camera cannot tear a frame's people from its
scene, and a weak prior on the cameras fixes the gauge this leaves. Points observed in both frames
(triangulated) stay where they are, as the paper's objective has them.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import torch
from scipy import ndimage
from scipy.optimize import least_squares

from multithumbs.determinism import fix_threads
from multithumbs.geometry import (axis_angle_to_matrix, camera_centre, matrix_to_axis_angle, project,
                                  vertex_normals)
from multithumbs.method.scale import depth_ratio_scale, mesh_to_points_scale
from multithumbs.method.views import register_views
from multithumbs.types import SharedSpace


@dataclass(frozen=True)
class AlignConfig:
    """Alignment settings (paper §3.2 defaults).

    Attributes:
        iterations: iterations of stages 1, 2 and 3 (stage 1 is the initialisation; its count is kept for
            the record, as in Algorithm 1, and costs nothing).
        lr_root: AdamW learning rate of the roots (m and rad per step).
        lr_camera: AdamW learning rate of the cameras.
        w2d_stage2: λ2D in stage 2.
        w2d_stage3: λ2D in stage 3.
        w_sil: λsil.
        w_depth: λdepth.
        refine_cameras: stage 3 also refines both cameras (False: the ``no_cam`` ablation).
        staged: run the stages in order (False: the ``no_stage`` ablation — every parameter from the
            estimator's own placement, optimised jointly under the full objective from the start).
        keypoint_confidence: 2D keypoints below this confidence are ignored.
        max_vertices: vertices per body used by the silhouette and depth losses (an even subsample).
        min_person_points: fewest scene points in a mask for a person to count in the scale estimate.
        depth_robust_scale: Geman-McClure scale (m) of the depth residual: vertices hidden behind another
            part of the same body (whose pixel shows that part) are outliers, not targets; 0 = plain squares.
            The kernel's pull fades beyond about this distance, so it must exceed the depth error left by a
            mesh whose size is a few percent off (0.15 m: standard suite full W-MPJPE 177.8 mm against 188.4
            with 0.05, which let the 2D term alone set each person's depth; 194.1 with plain squares).
        scale_method: ``"depth_ratio"`` (default: mesh over scene depth at the visible vertices' pixels) or
            ``"max_radius"`` (the paper's ratio of maximum centroid-to-vertex distances); both compare a
            mesh's size with its point cloud's, see :mod:`multithumbs.method.scale`.
        fit_scale_to_keypoints: for ``depth_ratio``, place each mesh at the depth where its joints
            reproject onto its 2D keypoints (:func:`fit_pelvis_to_keypoints`) before comparing depths, so
            the scale follows the meshes' metric size and not the estimator's depth, which monocular
            estimators get wrong by a per-track factor (False: the estimator's depth, as before).
        threads: torch intra-op threads of the alignment, its setup and optimisation loop, set for good with
            :func:`multithumbs.determinism.fix_threads` (0: leave torch's setting). The result's rounding
            depends on the count, so it is fixed, never toggled and restored (that raced across threads).
        points_follow_cameras: points observed in one boundary frame only move with that frame's camera
            in stage 3 (module docstring); False for point maps predicted in the world directly (VGGT's
            point head), which stay fixed while the cameras move, as in the paper.
        register_views: before the stages, correct the second boundary camera so both frames' static
            scenes agree (:func:`multithumbs.method.views.register_views`); part of the camera
            refinement, so off with ``refine_cameras=False``.
        view_samples: background points sampled per frame for that registration.
        view_robust_scale: its Cauchy scale and occlusion margin (m).
        view_smoothing_px: smoothing of the depth maps it compares with (pixels).
        w_camera_prior: weight of ``‖ω‖² + ‖C − C₀‖²`` (rad², m²) keeping stage 3's cameras near their
            registered poses: with points that follow their cameras, the people's losses leave a gauge
            (camera, its points and its people moving together) that this fixes.
    """

    iterations: tuple[int, int, int] = (500, 500, 1500)
    lr_root: float = 0.01
    lr_camera: float = 0.002
    w2d_stage2: float = 10.0
    w2d_stage3: float = 50.0
    w_sil: float = 0.01
    w_depth: float = 1.0
    refine_cameras: bool = True
    staged: bool = True
    keypoint_confidence: float = 0.3
    max_vertices: int = 400
    min_person_points: int = 20
    depth_robust_scale: float = 0.15
    scale_method: str = "depth_ratio"
    fit_scale_to_keypoints: bool = True
    threads: int = 1
    points_follow_cameras: bool = True
    register_views: bool = True
    view_samples: int = 2000
    view_robust_scale: float = 0.3
    view_smoothing_px: float = 3.0
    w_camera_prior: float = 1e-3


@dataclass(frozen=True)
class BoundaryPeople:
    """People at the two boundary frames of a cut, padded to the same count ``P``.

    Attributes:
        present: ``(2, P)`` bool.
        track_index: ``(2, P)`` int, the person's index in its shot's ``PersonTracks`` (-1 when padding).
        track_frame: ``(2, P)`` int, the shot-local frame the person was taken from (the boundary frame,
            or their nearest detection to it).
        local_vertices: ``(2, P, V, 3)`` posed vertices relative to the pelvis, zero global orientation.
        local_joints: ``(2, P, 24, 3)`` posed joints, same frame.
        orient_cam: ``(2, P, 3)`` estimated root orientation in the camera frame (axis-angle).
        pelvis_cam: ``(2, P, 3)`` estimated pelvis position in the camera frame (estimator's metres).
        keypoints: ``(2, P, 24, 3)`` 2D keypoints with confidence.
        masks: ``(2, P, H, W)`` bool.
        faces: ``(F, 3)`` the body mesh's faces.
    """

    present: np.ndarray
    track_index: np.ndarray
    track_frame: np.ndarray
    local_vertices: np.ndarray
    local_joints: np.ndarray
    orient_cam: np.ndarray
    pelvis_cam: np.ndarray
    keypoints: np.ndarray
    masks: np.ndarray
    faces: np.ndarray


@dataclass(frozen=True)
class AlignedBoundary:
    """Outcome of aligning one cut, in the cut's shared space brought to metric (mesh) scale.

    Attributes:
        cut_frame: ``t_b``.
        R: ``(2, 3, 3)`` refined world-to-camera rotations of the two boundary frames.
        t: ``(2, 3)`` refined translations.
        orient: ``(2, P, 3)`` world root orientations (axis-angle).
        pelvis: ``(2, P, 3)`` world pelvis positions.
        present: ``(2, P)`` bool, as in :class:`BoundaryPeople`.
        track_index: ``(2, P)`` as in :class:`BoundaryPeople`.
        track_frame: ``(2, P)`` as in :class:`BoundaryPeople`, or None (the boundary frames themselves).
        scale: factor applied to the shared space (nan when no person had points: 1 was used).
        point_map: ``(2, H, W, 3)`` scaled scene point maps of both frames, zero where ``point_valid`` is False.
        point_valid: ``(2, H, W)`` bool.
        losses: ``(N,)`` total loss per iteration over stages 2 and 3.
        method: which path ran: ``"three_stage"``, ``"joint"``, ``"no_align"``.
    """

    cut_frame: int
    R: np.ndarray
    t: np.ndarray
    orient: np.ndarray
    pelvis: np.ndarray
    present: np.ndarray
    track_index: np.ndarray
    scale: float
    point_map: np.ndarray
    point_valid: np.ndarray
    losses: np.ndarray = field(default_factory=lambda: np.zeros(0))
    method: str = "three_stage"
    track_frame: np.ndarray | None = None


def point_maps(space: SharedSpace, max_gap: float = 2.5) -> tuple[np.ndarray, np.ndarray]:
    """Scatter the points observed in each boundary frame into per-pixel maps ``(2, H, W, 3)`` and validity.

    Holes up to ``max_gap`` pixels from an observed pixel take the nearest observed point
    (``scipy.ndimage.distance_transform_edt``), so strided or sparse point maps still cover the image.
    """
    maps, valid, _, _ = point_maps_with_sources(space, max_gap)
    return maps, valid


def point_maps_with_sources(space: SharedSpace, max_gap: float = 2.5
                            ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`point_maps`, ``(2, H, W)`` bool: the pixel's point was observed in that frame only
    (unprojected from its depth, so it moves with its camera; module docstring), and ``(2, H, W)`` bool:
    the pixel holds a point of its own (not a filled hole)."""
    h, w = space.image_size
    maps = np.zeros((2, h, w, 3))
    valid = np.zeros((2, h, w), bool)
    single = np.zeros((2, h, w), bool)
    own = np.zeros((2, h, w), bool)
    for k in range(2):
        sel = space.observed[k]
        uv = np.round(space.pixels[k, sel]).astype(int)
        inside = (uv[:, 0] >= 0) & (uv[:, 0] < w) & (uv[:, 1] >= 0) & (uv[:, 1] < h)
        uv, pts = uv[inside], space.points[sel][inside]
        maps[k, uv[:, 1], uv[:, 0]] = pts
        valid[k, uv[:, 1], uv[:, 0]] = True
        single[k, uv[:, 1], uv[:, 0]] = ~space.observed[1 - k, sel][inside]
        own[k] = valid[k]
        if valid[k].any():
            dist, (iy, ix) = ndimage.distance_transform_edt(~valid[k], return_indices=True)
            fill = (dist <= max_gap) & ~valid[k]
            maps[k][fill] = maps[k][iy[fill], ix[fill]]
            single[k][fill] = single[k][iy[fill], ix[fill]]
            valid[k] |= fill
    return maps, valid, single & valid, own


def _root_pixel(keypoints: np.ndarray, min_conf: float) -> np.ndarray | None:
    """The 2D root: the pelvis keypoint, else the mid-hip, else None."""
    if keypoints[0, 2] >= min_conf:
        return keypoints[0, :2]
    if keypoints[1, 2] >= min_conf and keypoints[2, 2] >= min_conf:
        return 0.5 * (keypoints[1, :2] + keypoints[2, :2])
    return None


def _visible_vertices_cam(local_vertices: np.ndarray, local_normals: np.ndarray, orient_cam: np.ndarray,
                          pelvis_cam: np.ndarray, K: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Camera-frame vertices of the estimator's mesh that face the camera and project inside the mask.

    These are the vertices whose surface the person's point cloud samples, so their spread is comparable.
    """
    rot = axis_angle_to_matrix(orient_cam)
    verts = local_vertices @ rot.T + pelvis_cam
    facing = ((local_normals @ rot.T) * verts).sum(-1) < 0
    uv = np.round(project(verts, K)).astype(int)
    h, w = mask.shape
    inside = facing & (uv[:, 0] >= 0) & (uv[:, 0] < w) & (uv[:, 1] >= 0) & (uv[:, 1] < h)
    inside[inside] = mask[uv[inside, 1], uv[inside, 0]]
    return verts[inside]


def fit_pelvis_to_keypoints(local_joints: np.ndarray, orient_cam: np.ndarray, pelvis_cam: np.ndarray,
                            keypoints: np.ndarray, K: np.ndarray, min_conf: float = 0.3,
                            min_joints: int = 6) -> np.ndarray:
    """Camera-frame pelvis ``(3,)`` at which the posed body's joints best reproject onto its 2D keypoints.

    The body's size is metric (its shape), so the size of its projection fixes its depth: this is the
    depth a monocular estimator should have reported, free of its depth-along-the-ray error (which
    keeps the 2D position but not the projected size). Orientation and pose stay the estimator's.
    Least squares on confidence-weighted pixel residuals from ``pelvis_cam``; ``pelvis_cam`` itself
    when fewer than ``min_joints`` keypoints are confident or the fit fails.

    Args:
        local_joints: ``(24, 3)`` posed joints relative to the pelvis, zero global orientation.
        orient_cam: ``(3,)`` axis-angle camera-frame root orientation.
        pelvis_cam: ``(3,)`` the estimator's camera-frame pelvis (the starting point).
        keypoints: ``(24, 3)`` 2D keypoints ``u, v, confidence``.
        K: ``(3, 3)`` intrinsics.
    """
    use = keypoints[:, 2] >= min_conf
    if use.sum() < min_joints or pelvis_cam[2] <= 1e-6:
        return np.asarray(pelvis_cam, float).copy()
    offsets = (local_joints @ axis_angle_to_matrix(orient_cam).T)[use]
    weight = np.sqrt(keypoints[use, 2])[:, None]

    def residuals(x):
        # x = (u, v, log z) of the pelvis: the pixel and log-depth are well scaled for the solver.
        z = np.exp(x[2])
        pelvis = np.array([x[0] * z, x[1] * z, z])
        return ((project(offsets + pelvis, K) - keypoints[use, :2]) * weight).ravel()

    start = np.array([pelvis_cam[0] / pelvis_cam[2], pelvis_cam[1] / pelvis_cam[2], np.log(pelvis_cam[2])])
    fit = least_squares(residuals, start, method="lm", x_scale=np.array([0.01, 0.01, 0.05]))
    if not fit.success or not np.all(np.isfinite(fit.x)):
        return np.asarray(pelvis_cam, float).copy()
    z = float(np.exp(fit.x[2]))
    return np.array([fit.x[0] * z, fit.x[1] * z, z])


def keypoint_fitted_pelvis(people: BoundaryPeople, K: np.ndarray, min_conf: float) -> np.ndarray:
    """``(2, P, 3)`` camera-frame pelvis of every present boundary person from :func:`fit_pelvis_to_keypoints`."""
    out = np.array(people.pelvis_cam, float)
    for k in range(2):
        for p in np.nonzero(people.present[k])[0]:
            out[k, p] = fit_pelvis_to_keypoints(people.local_joints[k, p], people.orient_cam[k, p],
                                                people.pelvis_cam[k, p], people.keypoints[k, p], K[k], min_conf)
    return out


def estimate_space_scale(people: BoundaryPeople, space: SharedSpace, maps: np.ndarray, valid: np.ndarray,
                         min_points: int, method: str = "depth_ratio", pelvis_cam: np.ndarray | None = None) -> float:
    """Mesh-to-space scale at a cut (nan when no person has enough points).

    ``pelvis_cam`` ``(2, P, 3)``: where each mesh is placed in its camera frame for the ``depth_ratio``
    comparison (default: the estimator's placement; :func:`align_boundary` passes
    :func:`keypoint_fitted_pelvis`, whose depths follow from the meshes' metric size).
    """
    if method not in ("depth_ratio", "max_radius"):
        raise ValueError(f"scale_method {method!r}: use 'depth_ratio' or 'max_radius'")
    pelvis_cam = people.pelvis_cam if pelvis_cam is None else pelvis_cam
    first, second = [], []
    normals = vertex_normals(people.local_vertices, people.faces)
    h, w = valid.shape[1:]
    for k in range(2):
        for p in np.nonzero(people.present[k])[0]:
            mask = people.masks[k, p]
            verts = _visible_vertices_cam(people.local_vertices[k, p], normals[k, p], people.orient_cam[k, p],
                                          pelvis_cam[k, p], space.K[k], mask)
            if method == "max_radius":
                first.append(verts)
                second.append(maps[k][mask & valid[k]])
                continue
            uv = np.round(project(verts, space.K[k])).astype(int)
            ok = valid[k][uv[:, 1], uv[:, 0]] if len(uv) else np.zeros(0, bool)
            points = maps[k][uv[ok, 1], uv[ok, 0]]
            first.append(verts[ok, 2])
            second.append((points @ space.R[k].T + space.t[k])[:, 2])
    if method == "max_radius":
        return mesh_to_points_scale(first, second, min_points)
    return depth_ratio_scale(first, second, min_points)


def _camera_frame_roots(people: BoundaryPeople, R: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """World roots from the estimator's camera-frame roots through the cameras (``no_align`` placement)."""
    R_cam = axis_angle_to_matrix(people.orient_cam)                         # (2, P, 3, 3)
    orient = matrix_to_axis_angle(np.einsum("kji,kpjl->kpil", R, R_cam))    # R^T R_cam
    pelvis = np.einsum("kji,kpj->kpi", R, people.pelvis_cam - t[:, None])   # R^T (x - t)
    return orient, pelvis


def align_boundary(people: BoundaryPeople, space: SharedSpace, config: AlignConfig = AlignConfig(),
                   skip: bool = False) -> AlignedBoundary:
    """Place the boundary people of one cut in its shared space (``skip=True``: the ``no_align`` ablation)."""
    # One count for the result's rounding (multithumbs.determinism). One thread is also the faster: the
    # setup's tensor ops are small too, and on a busy machine a second thread's wake-up cost 15 ms per
    # 3802 x 3 product (the scale's visible-vertex projections), longer than the product itself.
    if config.threads > 0:
        fix_threads(config.threads)
    return _align_boundary(people, space, config, skip)


def _align_boundary(people: BoundaryPeople, space: SharedSpace, config: AlignConfig, skip: bool) -> AlignedBoundary:
    maps, valid, single_view, own = point_maps_with_sources(space)
    fitted = keypoint_fitted_pelvis(people, space.K, config.keypoint_confidence) if config.fit_scale_to_keypoints \
        else None
    scale = estimate_space_scale(people, space, maps, valid, config.min_person_points, config.scale_method, fitted)
    s = scale if np.isfinite(scale) and scale > 0 else 1.0
    maps = maps * s
    R0, t0 = space.R.astype(np.float64), space.t.astype(np.float64) * s
    follow = single_view & valid if config.points_follow_cameras else np.zeros_like(valid)
    if not skip and config.refine_cameras and config.register_views and follow.any():
        point_cam = np.einsum("kij,khwj->khwi", R0, maps) + t0[:, None, None]
        registration = register_views(point_cam, follow & ~people.masks.any(axis=1), space.K, R0, t0,
                                      config.view_samples, config.view_robust_scale, config.view_smoothing_px,
                                      observed=own)
        if registration.registered:  # frame 1's points move with its camera
            moved = (point_cam[1] - registration.t[1]) @ registration.R[1]
            maps[1] = np.where(follow[1][..., None], moved, maps[1])
            R0, t0 = registration.R, registration.t
    orient, pelvis = _camera_frame_roots(people, R0, t0)
    common = dict(cut_frame=space.cut_frame, present=people.present, track_index=people.track_index,
                  track_frame=people.track_frame, scale=scale,
                  point_map=maps, point_valid=valid)
    if skip:
        return AlignedBoundary(R=R0, t=t0, orient=orient, pelvis=pelvis, method="no_align", **common)
    if config.staged:
        pelvis = _stage1_roots(people, maps, valid, pelvis, config.keypoint_confidence)
    problem = _Problem(people, space, maps, valid, config, single_view=single_view, cameras=(R0, t0))
    state = problem.state(R0, t0, orient, pelvis)
    losses = []
    if config.staged:
        losses += problem.run(state, config.iterations[1], stage=2)
        losses += problem.run(state, config.iterations[2], stage=3)
    else:
        losses += problem.run(state, config.iterations[1] + config.iterations[2], stage=3)
    R, t, orient, pelvis = problem.export(state)
    common["point_map"] = problem.moved_point_maps(R, t)
    return AlignedBoundary(R=R, t=t, orient=orient, pelvis=pelvis, losses=np.asarray(losses),
                           method="three_stage" if config.staged else "joint", **common)


def _stage1_roots(people: BoundaryPeople, maps: np.ndarray, valid: np.ndarray, fallback: np.ndarray,
                  min_conf: float) -> np.ndarray:
    """Stage 1: each root at the scene point under its 2D root keypoint (nearest valid pixel in the mask)."""
    pelvis = fallback.copy()
    h, w = valid.shape[1:]
    for k in range(2):
        for p in np.nonzero(people.present[k])[0]:
            uv = _root_pixel(people.keypoints[k, p], min_conf)
            if uv is None:
                continue
            usable = valid[k] & people.masks[k, p]
            if not usable.any():
                continue
            ys, xs = np.nonzero(usable)
            nearest = np.argmin((xs - uv[0]) ** 2 + (ys - uv[1]) ** 2)
            if (xs[nearest] - uv[0]) ** 2 + (ys[nearest] - uv[1]) ** 2 <= 15 ** 2:
                pelvis[k, p] = maps[k, ys[nearest], xs[nearest]]
    return pelvis


DTYPE = torch.float64
"""Precision of the alignment's optimisation (float32 measured 6% faster per stage-3 iteration, 2.02 against
2.15 ms: the loop is bound by op count, so the precision is not worth trading)."""

_SKEW_BASIS = torch.zeros(3, 9, dtype=DTYPE)  # [k]x = [[0, -z, y], [z, 0, -x], [-y, x, 0]], flattened
_SKEW_BASIS[0, 7], _SKEW_BASIS[0, 5] = 1.0, -1.0
_SKEW_BASIS[1, 2], _SKEW_BASIS[1, 6] = 1.0, -1.0
_SKEW_BASIS[2, 3], _SKEW_BASIS[2, 1] = 1.0, -1.0
_ROTVEC_BASIS = torch.cat([_SKEW_BASIS, torch.kron(torch.eye(3, dtype=DTYPE), torch.ones(1, 3, dtype=DTYPE)),
                           torch.kron(torch.ones(1, 3, dtype=DTYPE), torch.eye(3, dtype=DTYPE))], dim=1)
"""``(3, 27)``: ``k @ _ROTVEC_BASIS`` holds, for every entry ``(i, j)`` of a 3x3 matrix, ``[k]x[i, j]``,
``k[i]`` and ``k[j]``."""
_EYE9 = torch.eye(3, dtype=DTYPE).flatten()


def _rotvec_to_rotmat(rotvec: torch.Tensor, epsilon: float = 1e-6) -> torch.Tensor:
    """``(N, 3)`` axis-angle to ``(N, 3, 3)``: ``roma.rotvec_to_rotmat`` to rounding, in a third of the tensor ops.

    The same Rodrigues formula ``I + sin θ [k]x + (1 - cos θ) (k kᵀ - I)`` and the same first-order
    ``I + [r]x`` below ``epsilon`` (the cameras' rotation starts at exactly zero), written on ``(N, 9)``
    after one small matrix product: the optimisation loops are bound by the number of tensor ops.
    """
    theta = torch.linalg.vector_norm(rotvec, dim=-1, keepdim=True)
    clamped = theta.clamp_min(epsilon)
    skew, row, col = ((rotvec / clamped) @ _ROTVEC_BASIS.to(rotvec.dtype)).split(9, dim=-1)
    eye = _EYE9.to(rotvec.dtype)
    rodrigues = eye + torch.sin(theta) * skew + (1 - torch.cos(theta)) * (row * col - eye)
    first_order = eye + clamped * skew   # below epsilon, clamped * (r / clamped) = r
    return torch.where(theta < epsilon, first_order, rodrigues).reshape(-1, 3, 3)


class _Problem:
    """The batched alignment objective of one cut (tensors over 2 frames x P people, flattened to ``2P``).

    Written for a loop bound by the count of tensor ops, not arithmetic: each root is one ``(6,)``
    parameter row (axis-angle, pelvis) and both cameras one ``(2, 6)`` tensor (rotation update,
    centre); joints and the vertex subsample are posed in one product; intrinsics and the 2D
    normalisation are folded into each camera's ``3x3``; every mean's count and λ is a precomputed
    weight; the depth loss's lookups are flat gathers. Points are stored coordinate-major
    (``(2P, 3, N)``), so posing is ``R X + t`` in one ``baddbmm`` and the sums over coordinates are
    adds of contiguous rows.
    """

    def __init__(self, people: BoundaryPeople, space: SharedSpace, maps: np.ndarray, valid: np.ndarray,
                 config: AlignConfig, single_view: np.ndarray | None = None,
                 cameras: tuple[np.ndarray, np.ndarray] | None = None):
        """``single_view`` ``(2, H, W)``: pixels whose point moves with its camera (None: none does);
        ``cameras``: the cameras ``(R, t)`` the maps were made with (default: the space's)."""
        self.config = config
        h, w = space.image_size
        norm = 0.5 * max(h, w)
        self.norm = norm
        self.size = (h, w)
        v_count = people.local_vertices.shape[2]
        self.vertex_ids = np.linspace(0, v_count - 1, min(config.max_vertices, v_count)).round().astype(int)
        as_t = lambda a: torch.as_tensor(np.asarray(a), dtype=DTYPE)
        present = torch.as_tensor(people.present)
        self.p_count = p_count = present.shape[1]
        rows = 2 * p_count
        coordinate_major = lambda a: as_t(a).reshape(rows, *a.shape[-2:]).transpose(1, 2).contiguous()
        self.joint_count = people.local_joints.shape[2]
        self.vertex_count = len(self.vertex_ids)
        self.local_joints = coordinate_major(people.local_joints)                         # (2P, 3, J)
        self.local_points = torch.cat([self.local_joints,
                                       coordinate_major(people.local_vertices[:, :, self.vertex_ids])], dim=2)
        normals = vertex_normals(people.local_vertices, people.faces)[:, :, self.vertex_ids]
        self.local_normals = coordinate_major(normals)
        # Normalised pixels (units of half the larger image side) come straight out of K_n = diag(1/norm, 1/norm, 1) K.
        self.K_norm = torch.tensor([1.0 / norm, 1.0 / norm, 1.0], dtype=DTYPE)[:, None] * as_t(space.K)
        kp = people.keypoints
        kp_weight = as_t(np.where(kp[..., 2] >= config.keypoint_confidence, kp[..., 2], 0.0)) * present[..., None]
        self.kp_uv = coordinate_major(kp[..., :2] / norm)                                 # (2P, 2, J)
        kp_mean = (kp_weight / kp_weight.sum().clamp(min=1e-9)).reshape(rows, 1, kp.shape[-2])  # a weighted mean
        self.kp_weight = {2: config.w2d_stage2 * kp_mean, 3: config.w2d_stage3 * kp_mean}
        masks = people.masks
        others = np.zeros_like(masks)
        for k in range(2):
            union = masks[k].any(axis=0)
            others[k] = union[None] & ~masks[k]
        # Distance (in normalised units) from each pixel to the person's mask; pixels of others count as 0.
        dist = np.zeros(masks.shape, np.float32)
        for k in range(2):
            for p in np.nonzero(people.present[k])[0]:
                outside = ~(masks[k, p] | others[k, p])
                dist[k, p] = ndimage.distance_transform_edt(outside) / norm if masks[k, p].any() else 0.0
        self.sil_dist = torch.as_tensor(dist, dtype=DTYPE).reshape(-1, 1, h, w)
        # grid_sample's coordinates (align_corners): pixel / (size - 1) * 2 - 1, from normalised pixels.
        self.grid_scale = torch.tensor([[norm * 2 / (w - 1)], [norm * 2 / (h - 1)]], dtype=DTYPE)
        presence = present.to(DTYPE).reshape(rows, 1)
        self.sil_weight = config.w_sil * presence / (presence.sum() * self.vertex_count).clamp(min=1)
        # Depth: which pixels of each person count (in the mask, a valid scene point, person present) and
        # the scene points, flattened for one gather each: person (k, p)'s pixel i is at (k P + p) H W + i.
        usable = torch.as_tensor(masks) & torch.as_tensor(valid)[:, None] & present[..., None, None]
        self.depth_usable = usable.reshape(-1)
        self.person_offset = (torch.arange(rows) * (h * w))[:, None]
        self.frame_offset = (torch.arange(2).repeat_interleave(p_count) * (h * w))[:, None]
        self.point_map = as_t(maps).reshape(-1, 3)
        # Points that move with their camera: their camera-frame coordinates under the maps' cameras are
        # what stays fixed (module docstring).
        R_maps, t_maps = (space.R, space.t) if cameras is None else cameras
        follow = np.zeros((2, h, w), bool) if single_view is None or not config.points_follow_cameras \
            else np.asarray(single_view, bool) & valid
        self.maps_np, self.follow_np = maps, follow
        self.point_cam_np = np.einsum("kij,khwj->khwi", np.asarray(R_maps, float), maps) + \
            np.asarray(t_maps, float)[:, None, None]
        self.follow = torch.as_tensor(follow.reshape(-1))
        self.any_follow = bool(follow.any())
        self.point_cam = as_t(self.point_cam_np).reshape(-1, 3)

    def state(self, R, t, orient, pelvis) -> dict[str, torch.Tensor]:
        as_t = lambda a: torch.as_tensor(np.asarray(a), dtype=DTYPE)
        R = as_t(R)
        camera = torch.cat([torch.zeros(2, 3, dtype=DTYPE), camera_centre(R, as_t(t))], dim=-1)
        return {"R0": R, "C0": camera[:, 3:].clone(),
                "camera": camera.requires_grad_(True),                              # (2, 6): rotation update, centre
                "roots": torch.cat([as_t(orient), as_t(pelvis)], dim=-1).requires_grad_(True)}  # (2, P, 6)

    def cameras(self, state) -> tuple[torch.Tensor, torch.Tensor]:
        return self._cameras(_rotvec_to_rotmat(state["camera"][:, :3]), state)

    @staticmethod
    def _cameras(update: torch.Tensor, state) -> tuple[torch.Tensor, torch.Tensor]:
        R = update @ state["R0"]
        t = -(R @ state["camera"][:, 3:].unsqueeze(-1)).squeeze(-1)
        return R, t

    def _projection(self, R: torch.Tensor, t: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Per person row: ``(2P, 3, 3)`` ``K_n R`` and ``(2P, 3, 1)`` ``K_n t`` of their frame's camera."""
        matrix = (self.K_norm @ R).repeat_interleave(self.p_count, dim=0)
        offset = (self.K_norm @ t.unsqueeze(-1)).repeat_interleave(self.p_count, dim=0)
        return matrix, offset

    def loss(self, state, stage: int, fixed_cameras: tuple[torch.Tensor, torch.Tensor] | None = None) -> torch.Tensor:
        """The stage's objective; ``fixed_cameras`` ``(R, t)`` when the cameras are not optimised."""
        cfg = self.config
        roots = state["roots"].reshape(-1, 6)
        if fixed_cameras is None:  # one rotation call for the roots and the camera updates
            rotations = _rotvec_to_rotmat(torch.cat([roots[:, :3], state["camera"][:, :3]]))
            rot, update = rotations[:-2], rotations[-2:]
            R, t = self._cameras(update, state)
        else:
            rot = _rotvec_to_rotmat(roots[:, :3])
            R, t = fixed_cameras
        local = self.local_joints if stage == 2 else self.local_points
        world = torch.baddbmm(roots[:, 3:].unsqueeze(-1), rot, local)            # (2P, 3, N)
        matrix, offset = self._projection(R, t)
        h = torch.baddbmm(offset, matrix, world)
        uv = h[:, :2] / h[:, 2:].clamp(min=1e-6)                                  # normalised pixels
        if stage == 2:
            return ((uv - self.kp_uv).square() * self.kp_weight[2]).sum()
        uv, vuv = uv.split([self.joint_count, self.vertex_count], dim=2)
        verts = world[:, :, self.joint_count:]
        loss2d = ((uv - self.kp_uv).square() * self.kp_weight[3]).sum()
        # Silhouette: bilinear sample of the distance transform at the projected vertices.
        grid = (vuv * self.grid_scale - 1).transpose(1, 2).unsqueeze(1)           # (2P, 1, V, 2)
        sil = torch.nn.functional.grid_sample(self.sil_dist, grid, align_corners=True, padding_mode="border")
        loss_sil = (sil.reshape(self.sil_weight.shape[0], self.vertex_count) * self.sil_weight).sum()
        # Depth: camera-facing vertices inside the mask vs the scene point at their pixel.
        with torch.no_grad():  # which vertices and pixels: a selection, not a gradient path
            normal_z = (R.repeat_interleave(self.p_count, dim=0)[:, 2:] @ rot) @ self.local_normals   # (2P, 1, V)
            pixels = (vuv * self.norm).round().long()
            height, width = self.size
            pixel = pixels[:, 1].clamp(0, height - 1) * width + pixels[:, 0].clamp(0, width - 1)  # (2P, V)
            use = self.depth_usable[self.person_offset + pixel] & (normal_z[:, 0] < 0)
            flat = (self.frame_offset + pixel).flatten()
            target = self.point_map.index_select(0, flat).reshape(*pixel.shape, 3).transpose(1, 2)
            robust = cfg.depth_robust_scale > 0
            sigma2 = cfg.depth_robust_scale ** 2
            use = use.to(DTYPE)
            depth_weight = use * (cfg.w_depth * (sigma2 if robust else 1.0) / use.sum().clamp(min=1))
        diff = verts - target
        if self.any_follow:  # those points are fixed in their camera's frame: compare there
            with torch.no_grad():
                target_cam = self.point_cam.index_select(0, flat).reshape(*pixel.shape, 3).transpose(1, 2)
                follow = self.follow[flat].reshape(pixel.shape).unsqueeze(1)
            rows_R, rows_t = R.repeat_interleave(self.p_count, dim=0), t.repeat_interleave(self.p_count, dim=0)
            diff = torch.where(follow, torch.baddbmm(rows_t.unsqueeze(-1), rows_R, verts) - target_cam, diff)
        d2 = diff.square().sum(1)
        if robust:  # Geman-McClure, in m²: σ² d² / (d² + σ²) (σ² is in the weight), flat for outliers
            d2 = d2 / (d2 + sigma2)
        loss = loss2d + loss_sil + (d2 * depth_weight).sum()
        if fixed_cameras is None:
            loss = loss + cfg.w_camera_prior * (
                state["camera"][:, :3].square().sum() + (state["camera"][:, 3:] - state["C0"]).square().sum())
        return loss

    def moved_point_maps(self, R: np.ndarray, t: np.ndarray) -> np.ndarray:
        """``(2, H, W, 3)`` the point maps under cameras ``(R, t)``: points that follow their camera moved."""
        moved = np.einsum("kji,khwj->khwi", R, self.point_cam_np - t[:, None, None])   # R^T (x_cam - t)
        return np.where(self.follow_np[..., None], moved, self.maps_np)

    def run(self, state, iterations: int, stage: int) -> list[float]:
        if iterations <= 0:
            return []
        cfg = self.config
        groups = [{"params": [state["roots"]], "lr": cfg.lr_root}]
        refine = stage == 3 and cfg.refine_cameras
        fixed = None
        if refine:
            groups.append({"params": [state["camera"]], "lr": cfg.lr_camera})
        else:
            with torch.no_grad():
                fixed = self.cameras(state)
        # fused: one kernel per parameter group (the loop is bound by op count).
        opt = torch.optim.AdamW(groups, weight_decay=0.0, fused=True)
        # Linear decay to a tenth: large early steps, settled late ones.
        sched = torch.optim.lr_scheduler.LambdaLR(opt, lambda i: 1.0 - 0.9 * i / iterations)
        losses = []
        for _ in range(iterations):
            opt.zero_grad(set_to_none=True)
            loss = self.loss(state, stage, fixed)
            loss.backward()
            opt.step()
            sched.step()
            losses.append(float(loss.detach()))
        return losses

    def export(self, state) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        with torch.no_grad():
            R, t = self.cameras(state)
            roots = state["roots"].detach().double().numpy()
            return R.double().numpy(), t.double().numpy(), roots[..., :3].copy(), roots[..., 3:].copy()
