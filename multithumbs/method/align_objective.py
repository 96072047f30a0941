"""The batched objective of one cut's alignment (:mod:`multithumbs.method.align`'s stages 2 and 3).

Every person of both boundary frames is one row of one tensor program: 2D reprojection, silhouette
(distance transform of the masks) and depth losses against the shared space, optionally with the two
cameras free, optimised with fused AdamW on one torch thread. Conventions and loss units: see
:mod:`multithumbs.method.align`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import torch
from scipy import ndimage

from multithumbs.geometry import camera_centre, vertex_normals

if TYPE_CHECKING:  # annotations only: align.py builds the problem from these
    from multithumbs.method.align import AlignConfig, BoundaryPeople
    from multithumbs.types import SharedSpace


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
