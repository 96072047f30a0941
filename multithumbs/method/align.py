"""Scale and three-stage alignment of boundary meshes to a shared space (paper §3.1–3.2, Algorithm 1).

At a cut, the people of the last frame before it (index 0) and the first frame after it (index 1)
are placed in the cut's shared space:

1. scale: the space is brought to the meshes' metric scale (:mod:`multithumbs.method.scale`);
2. stage 1: each root starts at the scene point under its 2D root keypoint;
3. stage 2: roots (pelvis position Γ, orientation Φ) are refined under the 2D reprojection loss;
4. stage 3: roots and both boundary cameras are refined under 2D + silhouette + depth losses;
5. a root whose camera-frame depth has left the estimator's by more than ``max_depth_departure`` is put back
   where the estimator saw it: the scene points that moved it were not on that person.

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
scene, and a prior on the cameras (``AlignConfig.w_camera_prior``) fixes the gauge this leaves and keeps
the people's depths from dragging the registered cameras. Points observed in both frames
(triangulated) stay where they are, as the paper's objective has them.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np
from scipy import ndimage
from scipy.optimize import least_squares

from multithumbs.determinism import fix_threads
from multithumbs.geometry import axis_angle_to_matrix, matrix_to_axis_angle, project, rotation_angle, vertex_normals
from multithumbs.method.align_objective import _Problem
from multithumbs.method.config import AlignConfig  # noqa: F401  (defined there without torch; re-exported)
from multithumbs.method.people_cameras import cameras_from_people
from multithumbs.method.scale import depth_ratio_scale, mesh_to_points_scale
from multithumbs.method.views import register_views
from multithumbs.types import SharedSpace


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
        appearance: ``(2, P, D)`` appearance descriptors near the cut (:mod:`multithumbs.appearance`), or
            None; the people-based cameras use them to tell who is who across a reverse cut.
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
    appearance: np.ndarray | None = None


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
        method: which path ran: ``"three_stage"``, ``"joint"``, ``"no_align"``, ``"people"`` (the cameras
            and the matched people's roots from :mod:`multithumbs.method.people_cameras`, no stages).
        cameras_from: where the boundary cameras came from: ``"scene"`` (the shared space), ``"people"``
            (:mod:`multithumbs.method.people_cameras`, the space having fallen back) or ``"none"`` (the space
            fell back and nobody was seen on both sides with enough keypoints, e.g. close-ups: the cameras,
            and root distances across the cut, mean nothing).
        people_pairs: ``(M, 2)`` the boundary people (side-0, side-1 index) the people-based cameras matched.
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
    cameras_from: str = "scene"
    people_pairs: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), np.int64))


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
    cameras_from, people_pairs = "scene", np.zeros((0, 2), np.int64)
    if config.people_cameras not in ("fallback", "always", "never"):
        raise ValueError(f"people_cameras {config.people_cameras!r}: use 'fallback', 'always' or 'never'")
    # No scene cameras at all (nothing matched, or a homography's rotation only) ...
    no_scene = space.fallback in ("human_only", "rotation_only") or not valid.any()
    # ... or a pose found only by a fallback path (pooled neighbour frames, the people's own features),
    # which at a reverse cut is often a spurious match: checked against the people's.
    doubtful = bool(space.fallback) and not no_scene
    if config.people_cameras == "always" or (config.people_cameras == "fallback" and (no_scene or doubtful)):
        pelvis_people = fitted if fitted is not None else keypoint_fitted_pelvis(people, space.K,
                                                                                 config.keypoint_confidence)
        found = cameras_from_people(people, pelvis_people, space.K, config.keypoint_confidence,
                                    w_appearance=config.people_w_appearance,
                                    unmatched_cost=config.people_unmatched_cost)
        scene_rotation = space.R[1] @ space.R[0].T
        agrees = found.found and float(np.rad2deg(rotation_angle(found.R[1], scene_rotation))) <= \
            config.people_agreement_deg
        if found.found and (no_scene or config.people_cameras == "always" or not agrees):
            # The people's metric frame: camera 0 is the world, the space's points are not used.
            R0, t0, cameras_from, people_pairs = found.R, found.t, "people", found.pairs
            valid = np.zeros_like(valid)
            single_view = np.zeros_like(single_view)
        elif no_scene:
            cameras_from = "none"
    elif no_scene:
        cameras_from = "none"
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
    common = dict(cut_frame=space.cut_frame, present=people.present, track_index=people.track_index,
                  track_frame=people.track_frame, scale=scale,
                  point_map=maps, point_valid=valid, cameras_from=cameras_from, people_pairs=people_pairs)
    if cameras_from == "people":
        # The matched people at their roots triangulated by both views, the others at their keypoint-fitted
        # depth. The stages are not run: with no scene points their losses are each frame's 2D alone, which
        # moves each side's copy of a person along its own rays and undoes the triangulation (dialogue suite:
        # W-MPJPE 56.4 mm with them, 43.1 without; docs/RESULTS.md).
        placed = dataclasses.replace(people, pelvis_cam=fitted if fitted is not None else pelvis_people)
        orient, pelvis = _camera_frame_roots(placed, R0, t0)
        for (i, j), (rot, root) in zip(people_pairs, found.roots):
            orient[0, i], pelvis[0, i] = rot, root
            orient[1, j], pelvis[1, j] = rot, root
        return AlignedBoundary(R=R0, t=t0, orient=orient, pelvis=pelvis, method="no_align" if skip else "people",
                               **common)
    orient, pelvis = _camera_frame_roots(people, R0, t0)
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
    _put_back_departed(people, R, t, orient, pelvis, config.max_depth_departure)
    common["point_map"] = problem.moved_point_maps(R, t)
    return AlignedBoundary(R=R, t=t, orient=orient, pelvis=pelvis, losses=np.asarray(losses),
                           method="three_stage" if config.staged else "joint", **common)


def _put_back_departed(people: BoundaryPeople, R: np.ndarray, t: np.ndarray, orient: np.ndarray, pelvis: np.ndarray,
                       max_departure: float) -> None:
    """Put back, in place, the aligned roots (world ``orient, pelvis (2, P, 3)``) whose camera-frame depth
    departs from the estimator's by more than ``max_departure`` of it: where the estimator saw them,
    through the refined cameras ``R, t``."""
    depth = (np.einsum("kij,kpj->kpi", R, pelvis) + t[:, None])[..., 2]  # (2, P)
    reference = people.pelvis_cam[..., 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        departed = people.present & (reference > 0) & (np.abs(depth / reference - 1) > max_departure)
    if departed.any():  # inf: never
        back_orient, back_pelvis = _camera_frame_roots(people, R, t)
        orient[departed], pelvis[departed] = back_orient[departed], back_pelvis[departed]


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
