"""The user's SMPL model files: convert an official chumpy pickle to plain numpy once, and prove it.

Official SMPL ``.pkl`` files hold chumpy objects, which do not load on Python 3.11.
:func:`convert_and_verify` converts with :func:`multithumbs.body.model.convert_smpl_pickle`, then poses
both models on the same random bodies — the pickle read through the chumpy-free unpickler and built as
``smplx.SMPL`` directly, and the converted ``.npz`` loaded the way every run loads it
(:class:`multithumbs.body.model.BodyModel`) — and publishes the ``.npz`` only if the meshes agree.
"""

from __future__ import annotations

import contextlib
import io
import os
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from multithumbs.body.model import read_smpl_pickle
from multithumbs.errors import InputError
from multithumbs.io import publish


@dataclass(frozen=True)
class ConversionCheck:
    """How the converted model compares with the pickle.

    Attributes:
        destination: the written ``.npz``.
        num_vertices: vertices of the model.
        num_poses: random bodies compared.
        max_vertex_difference: largest vertex distance between the two forward passes (metres).
        max_joint_difference: largest joint distance (metres).
    """

    destination: Path
    num_vertices: int
    num_poses: int
    max_vertex_difference: float
    max_joint_difference: float


def _pickle_model(arrays: dict[str, np.ndarray]):
    """``smplx.SMPL`` straight from the pickle's arrays (no conversion code involved beyond reading)."""
    import smplx
    from smplx.utils import Struct

    from multithumbs.body.model import SMPL_NUM_VERTICES, landmark_vertex_ids

    n = arrays["v_template"].shape[0]
    vertex_ids = None if n == SMPL_NUM_VERTICES else landmark_vertex_ids(
        arrays["v_template"], arrays["weights"], arrays["J_regressor"] @ arrays["v_template"])
    struct = Struct(**{k: v.astype(np.int64) if k in ("f", "kintree_table") else v for k, v in arrays.items()})
    with contextlib.redirect_stdout(io.StringIO()):
        return smplx.SMPL(model_path="", data_struct=struct, num_betas=10, vertex_ids=vertex_ids,
                          create_global_orient=False, create_body_pose=False, create_betas=False,
                          create_transl=False, dtype=torch.float64)


def convert_and_verify(source: str | Path, destination: str | Path, overwrite: bool = False, num_poses: int = 16,
                       tolerance: float = 1e-5, seed: int = 0) -> ConversionCheck:
    """Convert an SMPL ``.pkl`` to ``.npz`` and verify it by a forward pass of both models.

    Args:
        source: the official (chumpy) or any SMPL pickle.
        destination: the ``.npz`` to write (not replaced unless ``overwrite``).
        num_poses: random bodies (pose ~ N(0, 0.5 rad), betas ~ N(0, 1)) compared.
        tolerance: the largest vertex distance (metres) accepted.
        seed: seed of the random bodies.
    """
    from multithumbs.body.model import BodyModel, convert_smpl_pickle

    source, destination = Path(source), Path(destination)
    if not source.is_file():
        raise InputError(f"{source}: no such SMPL model file")
    if destination.suffix.lower() != ".npz":
        raise InputError(f"{destination}: the converted model is written as .npz")
    if destination.exists() and not overwrite:
        raise InputError(f"{destination}: already exists (pass --overwrite to replace it)")
    if not destination.parent.is_dir():
        raise InputError(f"{destination.parent}: output folder does not exist")
    arrays = read_smpl_pickle(source)
    fd, tmp = tempfile.mkstemp(prefix=f".{destination.stem}.", suffix=".npz", dir=destination.parent)
    os.close(fd)
    try:
        convert_smpl_pickle(source, tmp)
        converted = BodyModel(tmp, dtype=torch.float64)
        reference = _pickle_model(arrays)
        generator = torch.Generator().manual_seed(seed)
        orient = torch.randn(num_poses, 3, generator=generator, dtype=torch.float64) * 0.5
        pose = torch.randn(num_poses, 69, generator=generator, dtype=torch.float64) * 0.5
        betas = torch.randn(num_poses, 10, generator=generator, dtype=torch.float64)
        transl = torch.randn(num_poses, 3, generator=generator, dtype=torch.float64)
        with torch.no_grad():
            ours = converted.forward(orient, pose, betas, transl)
            theirs = reference(global_orient=orient, body_pose=pose, betas=betas, transl=transl)
        dv = float((ours.vertices - theirs.vertices).norm(dim=-1).max())
        dj = float((ours.joints - theirs.joints[:, :ours.joints.shape[1]]).norm(dim=-1).max())
        if not dv <= tolerance or not dj <= tolerance:
            raise InputError(f"{source}: the converted model differs from the pickle by {dv:.3g} m (vertices) and "
                             f"{dj:.3g} m (joints), above {tolerance:g} m; nothing written")
        publish(tmp, destination)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return ConversionCheck(destination, int(converted.num_vertices), num_poses, dv, dj)


__all__ = ["ConversionCheck", "convert_and_verify"]
