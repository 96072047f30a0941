"""EgoBody (ECCV 2022): Kinect views, per-recording transforms, SMPL pickles, valid frame ranges.

The data is gated (registration and licence at egobody.inf.ethz.ch). Layout (DATASETS.md §3)::

    data_info_release.csv     recording_name,start_frame,end_frame,body_idx_0,body_idx_1,body_idx_fpv,scene_name
    data_splits.csv           columns train,val,test (ragged)
    kinect_cam_params/kinect_<view>/Color.json          {f, c, camera_mtx, k}
    calibrations/<REC>/cal_trans/kinect_<id>to12_color.json   {"trans": 4x4 sub colour -> master colour}
    kinect_color/<REC>/<view>/frame_00001.jpg
    smpl_{interactee,camera_wearer}_{train,val}/<REC>/body_idx_<k>/results/frame_00001/000.pkl

The world frame is the master Kinect colour camera (OpenCV axes, metres), the frame of the SMPL fits;
``X_sub = inv(T_<id>to12) @ X_master``. Frames are the ids in the CSV's ``[start_frame, end_frame]``
whose image exists in every view; a person without a pickle at a frame is a gap. Ground-truth joints
come from gendered SMPL models (genders from the CSV), which the user supplies
(:func:`gendered_bodies`); the test split's ground truth is withheld by the dataset.
"""

from __future__ import annotations

import csv
import pickle
from pathlib import Path
from typing import Callable, Sequence

import numpy as np
import torch

from multithumbs.conventions import NUM_BETAS, NUM_BODY_JOINTS, NUM_JOINTS
from multithumbs.datasets.cameras import Camera, metric_extrinsics
from multithumbs.datasets.sequence import MultiViewSequence, PeopleSeries, read_betas, read_rgb, smpl_array
from multithumbs.errors import InputError
from multithumbs.io import read_json

INFO_CSV = "data_info_release.csv"
SPLITS_CSV = "data_splits.csv"
VIEWS = ("master", "sub_1", "sub_2", "sub_3", "sub_4")
KINECT_IDS = {"master": 12, "sub_1": 11, "sub_2": 13, "sub_3": 14, "sub_4": 15}
"""Kinect device id of each view (the calibration files name views by id)."""

DEFAULT_FPS = 30.0
"""Kinect frame rate [verify on real data]."""

GATED = "EgoBody is gated: register and sign the licence at egobody.inf.ethz.ch, then unpack it here"

BodyFactory = Callable[[str], object]
"""``gender -> body model`` (anything with ``forward(global_orient, body_pose, betas, transl)``)."""


def check_root(root: Path) -> None:
    """Raise InputError when ``root`` does not hold EgoBody (gated) or lacks its index files."""
    if not (root / INFO_CSV).is_file():
        raise InputError(f"{root / INFO_CSV}: missing ({GATED})")
    for rel in (SPLITS_CSV, "kinect_cam_params", "kinect_color", "calibrations"):
        if not (root / rel).exists():
            raise InputError(f"{root / rel}: missing (EgoBody layout)")


def read_info(root: Path) -> dict[str, dict[str, str]]:
    """``data_info_release.csv`` rows keyed by recording name."""
    path = root / INFO_CSV
    with open(path, newline="") as file:
        rows = list(csv.DictReader(file))
    needed = ("recording_name", "start_frame", "end_frame", "body_idx_0", "body_idx_1", "body_idx_fpv")
    if rows and any(k not in rows[0] for k in needed):
        missing = next(k for k in needed if k not in rows[0])
        raise InputError(f"{path}: missing column {missing!r}")
    return {row["recording_name"].strip(): row for row in rows}


def read_splits(root: Path) -> dict[str, str]:
    """Recording name -> ``"train"``, ``"val"`` or ``"test"`` from the ragged ``data_splits.csv``."""
    path = root / SPLITS_CSV
    out: dict[str, str] = {}
    with open(path, newline="") as file:
        for row in csv.DictReader(file):
            for split, name in row.items():
                name = (name or "").strip()
                if split and name and name.lower() != "nan":
                    out[name] = split.strip()
    return out


def find_recordings(root: str | Path) -> list[str]:
    """Recordings listed in ``data_info_release.csv`` that have Kinect frames under the root."""
    root = Path(root)
    check_root(root)
    return [name for name in sorted(read_info(root)) if (root / "kinect_color" / name).is_dir()]


def _gender(text: str, where: str) -> tuple[int, str]:
    parts = str(text).split()
    if len(parts) != 2 or not parts[0].isdigit() or parts[1] not in ("male", "female"):
        raise InputError(f"{where}: expected '<index> <male|female>', got {text!r}")
    return int(parts[0]), parts[1]


def read_color_json(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """``K`` and OpenCV distortion coefficients from a Kinect ``Color.json``."""
    data = read_json(path)
    try:
        K = np.asarray(data["camera_mtx"], dtype=np.float64)
        dist = np.asarray(data.get("k", []), dtype=np.float64).reshape(-1)
    except KeyError as missing:
        raise InputError(f"{path}: missing field {missing}") from None
    if K.shape != (3, 3):
        raise InputError(f"{path}: camera_mtx must be 3x3, got shape {K.shape}")
    return K, dist


def gendered_bodies(smpl_dir: str | Path | None) -> BodyFactory:
    """``gender -> BodyModel`` over ``SMPL_{MALE,FEMALE,NEUTRAL}.{npz,pkl}`` in ``smpl_dir`` (or its ``smpl/``).

    Models load when first asked for; a missing file is an InputError naming the file expected.
    Official ``.pkl`` files hold chumpy arrays: convert them once with ``multithumbs smpl-convert``.
    """
    from multithumbs.body.model import load_body_model

    if smpl_dir is None:
        raise InputError("EgoBody ground truth needs gendered SMPL models: pass --smpl-dir DIR holding "
                         "SMPL_MALE.npz and SMPL_FEMALE.npz (convert the official .pkl files with "
                         "`multithumbs smpl-convert`)")
    folder = Path(smpl_dir)
    if not folder.is_dir():
        raise InputError(f"{folder}: SMPL model folder does not exist")

    def factory(gender: str):
        name = f"SMPL_{gender.upper()}"
        for candidate in (folder / f"{name}.npz", folder / f"{name}.pkl", folder / "smpl" / f"{name}.npz",
                          folder / "smpl" / f"{name}.pkl"):
            if candidate.is_file():
                return load_body_model(candidate)
        raise InputError(f"{folder / (name + '.npz')}: missing SMPL model file for gender {gender!r} "
                         f"(.npz or .pkl; the SMPL models are licensed: download them from smpl.is.tue.mpg.de)")

    return factory


def load_egobody(root: str | Path, recording: str, bodies: BodyFactory | None = None,
                 views: Sequence[str] | None = None, fps: float | None = None) -> MultiViewSequence:
    """Load one EgoBody recording's Kinect views and SMPL ground truth.

    Args:
        root: the EgoBody root.
        recording: ``recording_YYYYMMDD_Sxx_Syy_nn``.
        bodies: ``gender -> body model`` for the ground-truth joints (:func:`gendered_bodies`); needed only
            to read ground truth (listing and frames work without it).
        views: Kinect views to use (default: every view with frames).
        fps: frames per second, default :data:`DEFAULT_FPS`.
    """
    root = Path(root)
    check_root(root)
    info = read_info(root)
    if recording not in info:
        raise InputError(f"{root / INFO_CSV}: no recording {recording!r}")
    row = info[recording]
    where = f"{root / INFO_CSV} {recording}"
    try:
        start, end = int(float(row["start_frame"])), int(float(row["end_frame"]))
    except ValueError:
        raise InputError(f"{where}: start_frame/end_frame are not integers") from None
    genders = {}
    for k in (0, 1):
        idx, gender = _gender(row[f"body_idx_{k}"], f"{where} body_idx_{k}")
        genders[idx] = gender
    interactee, _ = _gender(row["body_idx_fpv"], f"{where} body_idx_fpv")
    split = read_splits(root).get(recording)
    notes = []
    if split is None:
        raise InputError(f"{root / SPLITS_CSV}: recording {recording!r} is in no split")
    if split == "test":
        notes.append("test split: ground truth withheld by the dataset (challenge)")

    colour = root / "kinect_color" / recording
    available = [v for v in VIEWS if (colour / v).is_dir()]
    chosen = list(views) if views is not None else available
    if not chosen:
        raise InputError(f"{colour / 'master'}: missing (no Kinect view of {recording})")
    cameras = []
    for view in chosen:
        if view not in KINECT_IDS:
            raise InputError(f"views: unknown Kinect view {view!r} (known: {', '.join(VIEWS)})")
        if view not in available:
            raise InputError(f"{colour / view}: missing (Kinect view {view} of {recording})")
        K, dist = read_color_json(root / "kinect_cam_params" / f"kinect_{view}" / "Color.json")
        if view == "master":
            R, t = np.eye(3), np.zeros(3)
        else:
            path = root / "calibrations" / recording / "cal_trans" / f"kinect_{KINECT_IDS[view]}to12_color.json"
            data = read_json(path)
            if "trans" not in data:
                raise InputError(f"{path}: missing field 'trans'")
            trans = np.asarray(data["trans"], dtype=np.float64)
            if trans.shape != (4, 4) or abs(np.linalg.det(trans)) < 1e-12:
                raise InputError(f"{path}: 'trans' must be an invertible 4x4 matrix, got shape {trans.shape}")
            R, t, _ = metric_extrinsics(np.linalg.inv(trans), str(path))
        first = sorted((colour / view).glob("frame_*.jpg"))
        if not first:
            raise InputError(f"{colour / view / 'frame_00001.jpg'}: missing (no frames in view {view})")
        size = read_rgb(first[0]).shape[:2]
        lens = "radial" if dist.size and np.any(dist) else "pinhole"
        cameras.append(Camera(view, K, dist if lens == "radial" else np.zeros(0), lens, R, t, size))

    frame_ids = np.asarray([f for f in range(start, end + 1)
                            if all((colour / v / f"frame_{f:05d}.jpg").is_file() for v in chosen)], dtype=np.int64)
    if not len(frame_ids):
        raise InputError(f"{colour / chosen[0] / f'frame_{start:05d}.jpg'}: missing (no frame of [{start}, {end}] "
                         f"has an image in every view)")
    names = ("body_idx_0", "body_idx_1")

    def role(k: int) -> str:
        return "interactee" if k == interactee else "camera_wearer"

    def pkl_path(k: int, frame_id: int) -> Path:
        return (root / f"smpl_{role(k)}_{split}" / recording / f"body_idx_{k}" / "results"
                / f"frame_{frame_id:05d}" / "000.pkl")

    def image_path(camera: str, frame_id: int, undistorted: bool) -> tuple[Path, bool]:
        return colour / camera / f"frame_{frame_id:05d}.jpg", False

    def people_reader(ids: np.ndarray, wanted: Sequence[str], with_vertices: bool) -> PeopleSeries:
        if split == "test":
            raise InputError(f"{recording}: EgoBody withholds the test split's ground truth (challenge); "
                             f"use a train or val recording")
        gt_dir = root / f"smpl_{role(0)}_{split}" / recording
        if not gt_dir.is_dir():
            raise InputError(f"{gt_dir}: missing ({GATED}; the SMPL fits come in the smpl_* folders)")
        if bodies is None:
            gendered_bodies(None)  # raises the message naming what is needed
        return _read_people(ids, wanted, with_vertices, pkl_path, genders, bodies)

    return MultiViewSequence("egobody", recording, colour, tuple(cameras), frame_ids, float(fps or DEFAULT_FPS),
                             names, "kinect-master", tuple(notes), image_path, people_reader)


def _read_people(ids: np.ndarray, wanted: Sequence[str], with_vertices: bool, pkl_path, genders: dict[int, str],
                 bodies: BodyFactory) -> PeopleSeries:
    p, t = len(wanted), len(ids)
    orient, pose = np.zeros((p, t, 3)), np.zeros((p, t, NUM_BODY_JOINTS, 3))
    betas, transl = np.zeros((p, t, NUM_BETAS)), np.zeros((p, t, 3))
    joints, valid = np.zeros((p, t, NUM_JOINTS, 3)), np.zeros((p, t), bool)
    vertices = None
    for i, name in enumerate(wanted):
        k = int(name.rsplit("_", 1)[1])
        for j, frame_id in enumerate(ids):
            path = pkl_path(k, int(frame_id))
            if not path.is_file():
                continue  # no fit at this frame: a gap
            data = _load_pickle(path)
            for key in ("global_orient", "body_pose", "betas", "transl"):
                if key not in data:
                    raise InputError(f"{path}: missing field {key!r}")
            orient[i, j] = smpl_array(data["global_orient"], (3,), f"{path} global_orient")
            pose[i, j] = smpl_array(data["body_pose"], (NUM_BODY_JOINTS * 3,), f"{path} body_pose").reshape(-1, 3)
            betas[i, j] = read_betas(data["betas"], f"{path} betas")
            transl[i, j] = smpl_array(data["transl"], (3,), f"{path} transl")
            valid[i, j] = True
        if valid[i].any():
            body = bodies(genders[k])
            frames = np.flatnonzero(valid[i])
            with torch.no_grad():
                out = body.forward(orient[i, frames], pose[i, frames], betas[i, frames], transl[i, frames])
            joints[i, frames] = out.joints.detach().cpu().numpy().astype(np.float64)
            if with_vertices:
                verts = out.vertices.detach().cpu().numpy().astype(np.float32)
                if vertices is None:
                    vertices = np.zeros((p, t, verts.shape[1], 3), np.float32)
                if verts.shape[1] != vertices.shape[2]:
                    raise InputError(f"SMPL models: the {genders[k]} model has {verts.shape[1]} vertices, "
                                     f"another has {vertices.shape[2]}")
                vertices[i, frames] = verts
    if with_vertices and vertices is None:
        vertices = np.zeros((p, t, 0, 3), np.float32)
    gender_names = tuple(genders[int(n.rsplit("_", 1)[1])] for n in wanted)
    return PeopleSeries(tuple(wanted), np.asarray(ids, np.int64), orient, pose, betas, transl, joints, valid,
                        gender_names, vertices)


def _load_pickle(path: Path) -> dict:
    try:
        with open(path, "rb") as file:
            data = pickle.load(file, encoding="latin1")
    except Exception as error:  # pickle raises many types for a broken file
        raise InputError(f"{path}: not a readable SMPL pickle ({type(error).__name__})") from None
    if not isinstance(data, dict):
        raise InputError(f"{path}: expected a dict of SMPL parameters, got {type(data).__name__}")
    return data


__all__ = ["DEFAULT_FPS", "KINECT_IDS", "VIEWS", "check_root", "find_recordings", "gendered_bodies",
           "load_egobody", "read_color_json", "read_info", "read_splits"]
