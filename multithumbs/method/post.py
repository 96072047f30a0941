"""Post-processing (paper §3.5): temporal smoothness, body priors and cross-camera reprojection at cuts.

Minimises over every person's world SMPL parameters (orientation, translation, body pose, shape)

    λsmooth (Σ‖ΔJ‖² + wβ‖β‖² + wθ‖θ − θ̂‖²) + λcross L_cross + λ2D L_2D + λroot ‖Γ − Γ̂‖²

* ``J`` are world joints and ``Δ`` their first (the paper) or second difference in time (default, see
  :class:`PostConfig`); windows count within a shot and across a cut for a person matched
  across it (that is where continuity matters).
* VPoser's latent prior ``‖ζ‖²`` needs licensed weights; the documented substitute is a Gaussian prior
  on the deviation of the pose from its per-frame estimate θ̂ (``pose_prior="gaussian"``).
  ``pose_prior="vposer"`` is accepted only with a VPoser model supplied by the user.
* ``L_cross`` (paper Eq. 9): at each cut, a matched person's joints at ``t_b − 1`` projected with the
  camera of ``t_b`` against the keypoints observed at ``t_b``, and vice versa.
* ``L_2D`` and the root prior are the data terms that keep the smoothed motion on the observations
  (the paper's objective has none besides L_cross; without them smoothing alone drifts the roots).
  Each keypoint's residual in ``L_2D`` and ``L_cross`` goes through Geman-McClure
  (:attr:`PostConfig.robust_sigma_px`): a keypoint far off pulls with bounded force.

All terms are means (2D residuals in units of half the image's larger side), so weights do not depend
on the number of people, frames or joints. Joints come from SMPL's own kinematics
(:meth:`multithumbs.body.model.BodyModel.joints`), not the full mesh, which keeps this fast.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from multithumbs.conventions import NUM_JOINTS
from multithumbs.determinism import fix_threads
from multithumbs.method.config import PostConfig  # noqa: F401  (defined there without torch; re-exported)


@dataclass(frozen=True)
class PostInput:
    """World tracks of all people over the whole video.

    Attributes:
        global_orient: ``(P, T, 3)``; body_pose: ``(P, T, 23, 3)``; betas: ``(P, 10)``; transl: ``(P, T, 3)``.
        valid: ``(P, T)`` bool.
        keypoints: ``(P, T, 24, 3)`` observed 2D keypoints with confidence.
        K, R, t: ``(T, 3, 3)``, ``(T, 3, 3)``, ``(T, 3)`` world cameras.
        cut_frames: ``(C,)``.
        matched_at_cut: ``(P, C)`` bool, the person was matched across cut ``c`` (continuity across it counts).
        image_size: ``(H, W)``.
    """

    global_orient: np.ndarray
    body_pose: np.ndarray
    betas: np.ndarray
    transl: np.ndarray
    valid: np.ndarray
    keypoints: np.ndarray
    K: np.ndarray
    R: np.ndarray
    t: np.ndarray
    cut_frames: np.ndarray
    matched_at_cut: np.ndarray
    image_size: tuple[int, int]


@dataclass(frozen=True)
class PostOutput:
    """Refined parameters (same shapes as :class:`PostInput`) and the loss per iteration."""

    global_orient: np.ndarray
    body_pose: np.ndarray
    betas: np.ndarray
    transl: np.ndarray
    losses: np.ndarray


def _windows(valid: np.ndarray, cut_frames: np.ndarray, matched_at_cut: np.ndarray, order: int) -> np.ndarray:
    """``(P, T-order)`` bool: the window ``t .. t+order`` is scored for smoothness.

    A window may span a cut only for a person matched across it.
    """
    t_count = valid.shape[1]
    ok = np.ones((valid.shape[0], t_count - order), bool)
    for k in range(order + 1):
        ok &= valid[:, k:t_count - order + k]
    for c, cut in enumerate(cut_frames):
        for start in range(max(0, cut - order), min(cut, t_count - order)):
            ok[:, start] &= matched_at_cut[:, c]
    return ok


def post_process(data: PostInput, body, config: PostConfig = PostConfig(), vposer=None) -> PostOutput:
    """Refine all people's world SMPL parameters jointly (see the module docstring)."""
    if config.threads > 0:  # one count, one rounding (multithumbs.determinism)
        fix_threads(config.threads)
    return _post_process(data, body, config, vposer)


def _post_process(data: PostInput, body, config: PostConfig, vposer) -> PostOutput:
    if config.pose_prior == "vposer" and vposer is None:
        raise ValueError("pose_prior='vposer' needs a VPoser model; the default is the gaussian substitute")
    p_count, t_count = data.valid.shape
    if p_count == 0 or config.iterations <= 0:
        return PostOutput(data.global_orient, data.body_pose, data.betas, data.transl, np.zeros(0))
    if config.smooth_order not in (1, 2):
        raise ValueError(f"smooth_order must be 1 or 2, got {config.smooth_order}")
    terms = _Terms(data, config)
    as_t = lambda a: torch.as_tensor(np.asarray(a), dtype=torch.float64)
    pose0, transl0 = as_t(data.body_pose), as_t(data.transl)
    orient = as_t(data.global_orient).clone().requires_grad_(True)
    transl = transl0.clone().requires_grad_(True)
    body_pose = pose0.clone().requires_grad_(True)
    betas = as_t(data.betas).clone().requires_grad_(True)
    # fused: one kernel for the four parameters' update (the loop is bound by op count, not arithmetic).
    opt = torch.optim.AdamW([orient, transl, body_pose, betas], lr=config.lr, weight_decay=0.0, fused=True)
    sched = torch.optim.lr_scheduler.LambdaLR(opt, lambda i: 1.0 - 0.9 * i / config.iterations)
    losses = []
    for _ in range(config.iterations):
        opt.zero_grad(set_to_none=True)
        joints = body.joints(orient, body_pose, betas, transl).double()         # (P, T, 24, 3)
        loss = terms.loss(joints, body_pose, pose0, betas, transl, transl0)
        loss.backward()
        opt.step()
        sched.step()
        losses.append(float(loss.detach()))
    out = lambda x: x.detach().numpy().copy()
    keep = data.valid
    return PostOutput(np.where(keep[..., None], out(orient), data.global_orient),
                      np.where(keep[..., None, None], out(body_pose), data.body_pose), out(betas),
                      np.where(keep[..., None], out(transl), data.transl), np.asarray(losses))


class _Terms:
    """The objective of :func:`post_process` with every constant factored out of the loop.

    Each mean of the module docstring becomes a sum against a precomputed weight (mask over count,
    times the term's λ), and each camera's intrinsics and the 2D normalisation are folded into one
    ``(3, 3)`` matrix, so an iteration runs few tensor ops (the loop is bound by their count).
    """

    def __init__(self, data: PostInput, config: PostConfig):
        as_t = lambda a: torch.as_tensor(np.asarray(a), dtype=torch.float64)
        self.order = config.smooth_order
        valid = torch.as_tensor(data.valid)
        windows = torch.as_tensor(_windows(data.valid, data.cut_frames, data.matched_at_cut, config.smooth_order),
                                  dtype=torch.float64)
        # Smoothness: mean over joints of the squared difference, mean over scored windows.
        self.smooth_w = (config.w_smooth * windows / (windows.sum().clamp(min=1) * NUM_JOINTS))[..., None, None]
        vmask = valid.double()
        self.pose_w = (config.w_smooth * config.w_pose_prior * vmask / vmask.sum().clamp(min=1))[..., None, None]
        self.shape_w = config.w_smooth * config.w_shape / data.betas.shape[0]
        self.root_w = (config.w_root * vmask / vmask.sum().clamp(min=1))[..., None]
        # 2D: pixels in units of half the larger image side, through K R x + K t (K's last row is 0 0 1,
        # so the third coordinate is the camera depth).
        norm = 0.5 * max(data.image_size)
        scale = torch.tensor([1.0 / norm, 1.0 / norm, 1.0], dtype=torch.float64)[:, None]
        K, R, t = as_t(data.K), as_t(data.R), as_t(data.t)
        self.KR = scale * (K @ R)                                               # (T, 3, 3)
        self.Kt = (scale * (K @ t.unsqueeze(-1))).squeeze(-1)                    # (T, 3)
        kp = as_t(data.keypoints)
        kp_w = torch.where(kp[..., 2] >= config.keypoint_confidence, kp[..., 2], 0.0) * valid[..., None]
        # Coordinate-major (..., 2, 24) like the projections below.
        self.kp_uv = (kp[..., :2] / norm).transpose(-1, -2).contiguous()
        self.kp_w = config.w_2d * kp_w / kp_w.sum().clamp(min=1e-9)
        self.sigma2 = (config.robust_sigma_px / norm) ** 2  # 0: plain squares
        # Cross-camera terms (person, cut) matched with both boundary frames valid: each direction's
        # joints at one boundary frame against the keypoints at the other, each pair a weighted mean.
        pairs = [(p, src, dst) for p in range(data.valid.shape[0]) for i, c in enumerate(data.cut_frames)
                 if data.matched_at_cut[p, i] and data.valid[p, c - 1] and data.valid[p, c]
                 for src, dst in ((c - 1, c), (c, c - 1))]
        self.cross = None
        if pairs:
            person, src, dst = (torch.as_tensor([pair[k] for pair in pairs]) for k in range(3))
            w = kp_w[person, dst]
            self.cross = (person * data.valid.shape[1] + src, self.KR[dst], self.Kt[dst], self.kp_uv[person, dst],
                          config.w_cross * w / (w.sum(-1, keepdim=True).clamp(min=1e-9) * len(pairs)))

    @staticmethod
    def _normalised_pixels(points: torch.Tensor, KR: torch.Tensor, Kt: torch.Tensor) -> torch.Tensor:
        """``(..., 2, N)`` normalised pixels of ``points (..., N, 3)`` (depth clamped as in :func:`project`).

        Coordinate-major, so the gradient's sum over ``u, v`` for the shared depth adds two rows instead of
        reducing a trailing dimension of 2 (a slow reduction on CPU).
        """
        h = KR @ points.transpose(-1, -2) + Kt.unsqueeze(-1)
        return h[..., :2, :] / h[..., 2:, :].clamp(min=1e-6)

    def _reprojection(self, uv: torch.Tensor, kp_uv: torch.Tensor, weight: torch.Tensor) -> torch.Tensor:
        """Weighted sum over keypoints of ``ρ`` of the squared distance between ``(..., 2, N)`` projections
        and keypoints (``weight (..., N)``): Geman-McClure, ``σ² r² / (σ² + r²)``, or ``r²`` when ``σ`` is 0."""
        r2 = (uv - kp_uv).square().sum(-2)
        if self.sigma2 > 0:
            r2 = self.sigma2 * r2 / (r2 + self.sigma2)
        return (r2 * weight).sum()

    def loss(self, joints, body_pose, pose0, betas, transl, transl0) -> torch.Tensor:
        """The objective for world joints ``(P, T, 24, 3)`` of the current parameters (``pose0``,
        ``transl0``: the propagated estimates the priors pull towards)."""
        diff = joints[:, 1:] - joints[:, :-1]
        if self.order == 2:
            diff = diff[:, 1:] - diff[:, :-1]
        loss = (diff.square() * self.smooth_w).sum()
        loss = loss + ((body_pose - pose0).square() * self.pose_w).sum() + self.shape_w * betas.square().sum()
        loss = loss + self._reprojection(self._normalised_pixels(joints, self.KR, self.Kt), self.kp_uv, self.kp_w)
        loss = loss + ((transl - transl0).square() * self.root_w).sum()
        if self.cross is not None:
            rows, KR, Kt, kp_uv, weight = self.cross
            uv = self._normalised_pixels(joints.flatten(0, 1).index_select(0, rows), KR, Kt)
            loss = loss + self._reprojection(uv, kp_uv, weight)
        return loss
