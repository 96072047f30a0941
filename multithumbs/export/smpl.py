"""Per-person world SMPL parameters as ``.npz`` (one file per global person id).

Fields of ``person_<id>.npz`` (``T`` = frames of the video, every frame present; ``valid`` tells which
carry the person):

=================  ===============  ===========================================================================
field              shape / dtype    meaning
=================  ===============  ===========================================================================
``person_id``      () int64         global person id (stable across cuts)
``frames``         (T,) int64       video frame index of each row (0 .. T-1)
``valid``          (T,) bool        the person exists in that frame (rows where False hold the result's padding)
``fps``            () float64       frames per second of the video
``global_orient``  (T, 3) float64   axis-angle root orientation in the world frame
``body_pose``      (T, 23, 3)       axis-angle rotations of SMPL joints 1..23
``betas``          (10,) float64    shape
``transl``         (T, 3) float64   SMPL translation in the world frame (metres), as ``smplx``'s ``transl``
``joints``         (T, 24, 3)       world joints posed by the body model used for the export (metres)
``poses``          (T, 72) float64  AMASS-style alias: ``global_orient`` then ``body_pose`` flattened
``trans``          (T, 3) float64   AMASS-style alias of ``transl``
``mocap_framerate`` () float64      AMASS-style alias of ``fps``
``gender``         () str           ``"neutral"``
``world_up``       (3,) float64     the world's estimated up direction (:func:`multithumbs.export.posed.world_up`)
``cut_frames``     (C,) int64       first frame of each new shot
``shot``           (T,) int64       shot index of every frame
``track_ids``      (M, 2) int64     rows ``(shot, local track id)`` merged into this person (from ``id_map``)
``body_model``     () str           body model the joints came from (``procedural`` or the SMPL file)
=================  ===============  ===========================================================================

World frame and cameras follow :mod:`multithumbs.conventions`; the cameras are in ``cameras.npz``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from multithumbs.errors import InputError
from multithumbs.export.posed import shot_index
from multithumbs.io import save_npz_atomic
from multithumbs.types import WorldResult


def person_file_name(person_id: int, suffix: str) -> str:
    """The file name of one person's export, e.g. ``person_03.npz``."""
    return f"person_{int(person_id):02d}{suffix}"


def smpl_arrays(result: WorldResult, person: int, joints: np.ndarray, up: np.ndarray,
                body_source: str = "unknown") -> dict[str, np.ndarray]:
    """The arrays of one person's SMPL export (module docstring).

    Args:
        result: the reconstruction.
        person: row of ``result`` (not the global id).
        joints: ``(T, 24, 3)`` that person's world joints.
        up: ``(3,)`` world up direction.
        body_source: label of the body model.
    """
    if not 0 <= person < result.num_people:
        raise InputError(f"person: row {person} is out of range for {result.num_people} people")
    gid = int(result.person_ids[person])
    t = result.num_frames
    orient = np.asarray(result.global_orient[person], np.float64)
    pose = np.asarray(result.body_pose[person], np.float64)
    transl = np.asarray(result.transl[person], np.float64)
    rows = result.id_map[result.id_map[:, 2] == gid][:, :2] if result.id_map.size else np.zeros((0, 2), np.int64)
    return {
        "person_id": np.int64(gid), "frames": np.arange(t, dtype=np.int64), "valid": result.valid[person].copy(),
        "fps": np.float64(result.fps), "global_orient": orient, "body_pose": pose,
        "betas": np.asarray(result.betas[person], np.float64), "transl": transl,
        "joints": np.asarray(joints, np.float64),
        "poses": np.concatenate([orient, pose.reshape(t, -1)], axis=1), "trans": transl.copy(),
        "mocap_framerate": np.float64(result.fps), "gender": np.array("neutral"),
        "world_up": np.asarray(up, np.float64), "cut_frames": np.asarray(result.cut_frames, np.int64),
        "shot": shot_index(result).astype(np.int64), "track_ids": np.asarray(rows, np.int64).reshape(-1, 2),
        "body_model": np.array(str(body_source)),
    }


def write_smpl_npz(path: str | Path, result: WorldResult, person: int, joints: np.ndarray, up: np.ndarray,
                   body_source: str = "unknown") -> Path:
    """Write one person's world SMPL parameters (module docstring) to ``path`` atomically."""
    return save_npz_atomic(path, smpl_arrays(result, person, joints, up, body_source))
