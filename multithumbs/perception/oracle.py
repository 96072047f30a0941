"""Oracle perception: the per-shot tracks a perfect estimator would report, from ground truth.

For datasets (and their fixtures) whose clips have no estimator output yet, so the whole pipeline runs
and its geometric stages can be measured on their own: everything the method gets from perception is
exact; masks come from the ground truth's instance map when it has one (synthetic scenes) and are empty
otherwise (real datasets), appearance is then described from the pixels like any other source's.
Results from it are labelled ``perception: oracle``; never report them as a method's accuracy.
"""

from __future__ import annotations

import numpy as np
import roma
import torch

from multithumbs.types import GroundTruth, PersonTracks, pack_mask


def oracle_tracks(truth: GroundTruth, body, instance: np.ndarray | None = None) -> list[PersonTracks]:
    """Per-shot :class:`PersonTracks` in each frame's camera frame, from the true world parameters.

    ``instance`` ``(T, H, W)`` (person index per pixel, -1 elsewhere; synthetic ground truth has it) gives
    the masks; without it masks are empty.

    SMPL rotates about the shaped rest pelvis ``J0``, so moving a body by ``x -> R x + t`` maps the
    translation as ``transl' = R (J0 + transl) + t - J0`` and the root orientation as ``R @ orient``.
    """
    world = truth.world
    with torch.no_grad():
        pelvis_rest = body.rest_joints(np.asarray(world.betas, np.float64))[..., 0, :].double().numpy()  # (P, 3)
    h, w = world.image_size
    out = []
    for k, (a, b) in enumerate(world.shots().ranges):
        R, t = world.R[a:b], world.t[a:b]  # (T, 3, 3), (T, 3)
        orient_w = roma.rotvec_to_rotmat(torch.as_tensor(world.global_orient[:, a:b], dtype=torch.float64))
        orient_c = roma.rotmat_to_rotvec(torch.as_tensor(R, dtype=torch.float64)[None] @ orient_w).numpy()
        centre = pelvis_rest[:, None] + world.transl[:, a:b]  # (P, T, 3)
        transl_c = np.einsum("tij,ptj->pti", R, centre) + t[None] - pelvis_rest[:, None]
        valid = truth.visible[:, a:b] & world.valid[:, a:b]
        keep = valid.any(axis=1)
        n, T = int(keep.sum()), b - a
        out.append(PersonTracks(
            shot_index=k, start_frame=a, track_ids=np.flatnonzero(keep).astype(np.int64),
            global_orient=np.where(valid[keep, :, None], orient_c[keep], 0.0),
            body_pose=np.where(valid[keep, :, None, None], world.body_pose[keep, a:b], 0.0),
            betas=np.asarray(world.betas[keep], np.float64),
            transl=np.where(valid[keep, :, None], transl_c[keep], 0.0),
            keypoints2d=np.where(valid[keep, :, None, None], world.keypoints2d[keep, a:b], 0.0),
            masks=(np.zeros((n, T, h, (w + 7) // 8), np.uint8) if instance is None else
                   np.stack([pack_mask(instance[a:b] == p) for p in np.flatnonzero(keep)]).reshape(n, T, h, -1)),
            image_size=(h, w), K=np.asarray(world.K[a]),
            appearance=np.zeros((n, T, 1)), appearance_valid=np.zeros((n, T), bool), valid=valid[keep]))
    return out
