"""Scale and three-stage alignment of boundary meshes to a shared space (paper §3.1–3.2, Algorithm 1).

At a cut, the people of the last frame before it (index 0) and the first frame after it (index 1)
are placed in the cut's shared space:

1. scale: the space is brought to the meshes' metric scale (:mod:`multithumbs.method.scale`);
2. stage 1: each root starts at the scene point under its 2D root keypoint;
3. stage 2: roots (pelvis position Γ, orientation Φ) are refined under the 2D reprojection loss;
4. stage 3: roots and both boundary cameras are refined under 2D + silhouette + depth losses.

All people and both frames are one batched tensor program. Each body's pose and shape stay fixed
during alignment, so it is posed once (in its own pelvis-centred frame) before the loop.

Loss normalisation (the paper gives weights, not units): 2D residuals are in units of half the image's
larger side, the silhouette loss is the distance (same units) from a projected vertex to the person's
mask, the depth loss is the squared 3D distance (m²) between a camera-facing vertex inside the mask and
the scene point at its pixel. Each is a mean, so the weights do not depend on vertex or joint counts.
Silhouette distances treat pixels covered by other people as unknown (distance 0), so a limb hidden
behind someone else is not pulled out from behind them.
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass, field

import numpy as np
import torch
from scipy import ndimage
from scipy.optimize import least_squares

from multithumbs.geometry import (axis_angle_to_matrix, camera_centre, matrix_to_axis_angle, project,
                                  vertex_normals, world_to_camera)
from multithumbs.method.scale import depth_ratio_scale, mesh_to_points_scale
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
        threads: torch intra-op threads of the optimisation loop (0: leave torch's setting); see
            :func:`torch_threads`.
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
    h, w = space.image_size
    maps = np.zeros((2, h, w, 3))
    valid = np.zeros((2, h, w), bool)
    for k in range(2):
        sel = space.observed[k]
        uv = np.round(space.pixels[k, sel]).astype(int)
        inside = (uv[:, 0] >= 0) & (uv[:, 0] < w) & (uv[:, 1] >= 0) & (uv[:, 1] < h)
        uv, pts = uv[inside], space.points[sel][inside]
        maps[k, uv[:, 1], uv[:, 0]] = pts
        valid[k, uv[:, 1], uv[:, 0]] = True
        if valid[k].any():
            dist, (iy, ix) = ndimage.distance_transform_edt(~valid[k], return_indices=True)
            fill = (dist <= max_gap) & ~valid[k]
            maps[k][fill] = maps[k][iy[fill], ix[fill]]
            valid[k] |= fill
    return maps, valid


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
    maps, valid = point_maps(space)
    fitted = keypoint_fitted_pelvis(people, space.K, config.keypoint_confidence) if config.fit_scale_to_keypoints \
        else None
    scale = estimate_space_scale(people, space, maps, valid, config.min_person_points, config.scale_method, fitted)
    s = scale if np.isfinite(scale) and scale > 0 else 1.0
    maps = maps * s
    R0, t0 = space.R.astype(np.float64), space.t.astype(np.float64) * s
    orient, pelvis = _camera_frame_roots(people, R0, t0)
    common = dict(cut_frame=space.cut_frame, present=people.present, track_index=people.track_index,
                  track_frame=people.track_frame, scale=scale,
                  point_map=maps, point_valid=valid)
    if skip:
        return AlignedBoundary(R=R0, t=t0, orient=orient, pelvis=pelvis, method="no_align", **common)
    if config.staged:
        pelvis = _stage1_roots(people, maps, valid, pelvis, config.keypoint_confidence)
    problem = _Problem(people, space, maps, valid, config)
    state = problem.state(R0, t0, orient, pelvis)
    losses = []
    with torch_threads(config.threads):
        if config.staged:
            losses += problem.run(state, config.iterations[1], stage=2)
            losses += problem.run(state, config.iterations[2], stage=3)
        else:
            losses += problem.run(state, config.iterations[1] + config.iterations[2], stage=3)
    R, t, orient, pelvis = problem.export(state)
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


@contextlib.contextmanager
def torch_threads(count: int):
    """Run the block with ``count`` torch intra-op threads (0: leave the setting alone), then restore it.

    The method's optimisation loops run thousands of small tensor ops: splitting each across threads
    costs more in synchronisation than it saves (benchmarks/method.py, 150 frames: 21.4 s with 2 threads,
    19.0 s with one).
    """
    before = torch.get_num_threads()
    if count > 0:
        torch.set_num_threads(count)
    try:
        yield
    finally:
        torch.set_num_threads(before)


DTYPE = torch.float64
"""Precision of the alignment's optimisation (float32 measured no faster here: the loop is bound by op count)."""


class _Problem:
    """The batched alignment objective of one cut (tensors over 2 frames x P people)."""

    def __init__(self, people: BoundaryPeople, space: SharedSpace, maps: np.ndarray, valid: np.ndarray,
                 config: AlignConfig):
        self.config = config
        h, w = space.image_size
        self.norm = 0.5 * max(h, w)
        self.size = (h, w)
        v_count = people.local_vertices.shape[2]
        self.vertex_ids = np.linspace(0, v_count - 1, min(config.max_vertices, v_count)).round().astype(int)
        as_t = lambda a: torch.as_tensor(np.asarray(a), dtype=DTYPE)
        self.present = torch.as_tensor(people.present)
        self.K = as_t(space.K)
        self.local_joints = as_t(people.local_joints)
        self.local_vertices = as_t(people.local_vertices[:, :, self.vertex_ids])
        self.local_normals = as_t(vertex_normals(people.local_vertices, people.faces)[:, :, self.vertex_ids])
        kp = people.keypoints
        self.kp_uv = as_t(kp[..., :2])
        self.kp_weight = as_t(np.where(kp[..., 2] >= config.keypoint_confidence, kp[..., 2], 0.0)) \
            * self.present[..., None]
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
                dist[k, p] = ndimage.distance_transform_edt(outside) / self.norm if masks[k, p].any() else 0.0
        self.sil_dist = torch.as_tensor(dist, dtype=DTYPE).reshape(-1, 1, h, w)
        self.masks = torch.as_tensor(masks)
        self.point_map = as_t(maps)
        self.point_valid = torch.as_tensor(valid)

    def state(self, R, t, orient, pelvis) -> dict[str, torch.Tensor]:
        as_t = lambda a: torch.as_tensor(np.asarray(a), dtype=DTYPE)
        R = as_t(R)
        return {
            "R0": R, "cam_rot": torch.zeros(2, 3, dtype=DTYPE, requires_grad=True),
            "cam_centre": camera_centre(R, as_t(t)).clone().requires_grad_(True),
            "orient": as_t(orient).clone().requires_grad_(True),
            "pelvis": as_t(pelvis).clone().requires_grad_(True),
        }

    def cameras(self, state) -> tuple[torch.Tensor, torch.Tensor]:
        R = axis_angle_to_matrix(state["cam_rot"]) @ state["R0"]
        t = -(R @ state["cam_centre"].unsqueeze(-1)).squeeze(-1)
        return R, t

    def loss(self, state, stage: int) -> torch.Tensor:
        cfg = self.config
        R, t = self.cameras(state)
        rot = axis_angle_to_matrix(state["orient"])                                # (2, P, 3, 3)
        pelvis = state["pelvis"].unsqueeze(-2)
        joints = self.local_joints @ rot.transpose(-1, -2) + pelvis               # (2, P, 24, 3)
        R_b, t_b = R[:, None], t[:, None]
        uv = project(world_to_camera(joints, R_b, t_b), self.K[:, None])
        err2d = ((uv - self.kp_uv) / self.norm).pow(2).sum(-1)
        loss2d = (err2d * self.kp_weight).sum() / self.kp_weight.sum().clamp(min=1e-9)
        if stage == 2:
            return cfg.w2d_stage2 * loss2d
        verts = self.local_vertices @ rot.transpose(-1, -2) + pelvis              # (2, P, V, 3)
        cam = world_to_camera(verts, R_b, t_b)
        vuv = project(cam, self.K[:, None])
        # Silhouette: bilinear sample of the distance transform at the projected vertices.
        h, w = self.size
        grid = torch.stack([vuv[..., 0] / (w - 1) * 2 - 1, vuv[..., 1] / (h - 1) * 2 - 1], dim=-1)
        sil = torch.nn.functional.grid_sample(self.sil_dist, grid.reshape(-1, 1, grid.shape[-2], 2), align_corners=True,
                                              padding_mode="border").reshape(verts.shape[:-1])
        present = self.present[..., None].to(DTYPE)
        loss_sil = (sil * present).sum() / (present.sum() * verts.shape[-2]).clamp(min=1)
        # Depth: camera-facing vertices inside the mask vs the scene point at their pixel.
        with torch.no_grad():  # which vertices face the camera: a selection, not a gradient path
            normals_cam = self.local_normals @ (R.unsqueeze(1) @ rot).transpose(-1, -2)
            facing = normals_cam[..., 2] < 0
        ui = vuv[..., 0].detach().round().long().clamp(0, w - 1)
        vi = vuv[..., 1].detach().round().long().clamp(0, h - 1)
        frame = torch.arange(2)[:, None, None].expand_as(ui)
        person = torch.arange(ui.shape[1])[None, :, None].expand_as(ui)
        in_mask = self.masks[frame, person, vi, ui] & self.point_valid[frame, vi, ui] & facing
        in_mask &= self.present[..., None]
        target = self.point_map[frame, vi, ui]
        d2 = (verts - target).pow(2).sum(-1)
        if cfg.depth_robust_scale > 0:  # Geman-McClure, in m²: quadratic near 0, flat for outliers
            sigma2 = cfg.depth_robust_scale ** 2
            d2 = sigma2 * d2 / (d2 + sigma2)
        loss_depth = (d2 * in_mask).sum() / in_mask.sum().clamp(min=1)
        return cfg.w2d_stage3 * loss2d + cfg.w_sil * loss_sil + cfg.w_depth * loss_depth

    def run(self, state, iterations: int, stage: int) -> list[float]:
        if iterations <= 0:
            return []
        cfg = self.config
        groups = [{"params": [state["orient"], state["pelvis"]], "lr": cfg.lr_root}]
        if stage == 3 and cfg.refine_cameras:
            groups.append({"params": [state["cam_rot"], state["cam_centre"]], "lr": cfg.lr_camera})
        opt = torch.optim.AdamW(groups, weight_decay=0.0)
        # Linear decay to a tenth: large early steps, settled late ones.
        sched = torch.optim.lr_scheduler.LambdaLR(opt, lambda i: 1.0 - 0.9 * i / iterations)
        losses = []
        for _ in range(iterations):
            opt.zero_grad(set_to_none=True)
            loss = self.loss(state, stage)
            loss.backward()
            opt.step()
            sched.step()
            losses.append(float(loss.detach()))
        return losses

    def export(self, state) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        with torch.no_grad():
            R, t = self.cameras(state)
            return (R.double().numpy(), t.double().numpy(), state["orient"].detach().double().numpy(),
                    state["pelvis"].detach().double().numpy())
