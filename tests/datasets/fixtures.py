"""Tiny data roots with exactly the documented layouts (DATASETS.md), generated in tmp_path.

The fixture's truth is built independently of the loaders: a level world (+z up, floor at z = 0) in
which people stand (posed by the procedural SMPL-format body) and cameras look at them; the dataset's
world is that world moved by a known rigid transform, and the files store what the datasets store.
"""

from __future__ import annotations

import csv
import json
import pickle
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np
import torch
from scipy.spatial.transform import Rotation

from multithumbs.geometry import look_at

COLMAP_CAMERAS_HEADER = ("# Camera list with one line of data per camera:\n"
                         "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n"
                         "# Number of cameras: 3\n")
COLMAP_IMAGES_HEADER = ("# Image list with two lines of data per image:\n"
                        "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n"
                        "#   POINTS2D[] as (X, Y, POINT3D_ID)\n"
                        "# Number of images: 3, mean observations per image: 0\n")
COLMAP_POINTS_HEADER = ("# 3D point list with one line of data per point:\n"
                        "#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)\n"
                        "# Number of points: 20, mean track length: 0\n")

# The dataset's world is the level world moved by x_d = G x_level + g (a generic rigid motion).
G = Rotation.from_euler("xyz", [100.0, -20.0, 35.0], degrees=True).as_matrix()
g = np.array([0.4, -1.1, 2.3])
SMPL_TO_LEVEL = Rotation.from_euler("x", 90, degrees=True).as_matrix()
"""Turns SMPL's body frame (+y up, facing +z) to stand in the level world (+z up, facing -y)."""


@dataclass
class CaptureTruth:
    """What the fixture put where (dataset world unless said otherwise)."""

    frame_ids: list[int]
    people: dict[str, dict[str, np.ndarray]]   # name -> arrays over frames (T, ...)
    present: dict[str, np.ndarray]              # name -> (T,) bool
    cameras: dict[str, dict[str, np.ndarray]]   # name -> K, D, R, t (metric, dataset world), size (H, W)
    level_joints: dict[str, np.ndarray] = field(default_factory=dict)  # name -> (T, 24, 3) level world


def rest_pelvis(body, betas: np.ndarray) -> np.ndarray:
    return body.rest_joints(torch.as_tensor(betas, dtype=torch.float32)).numpy().astype(np.float64)[0]


def pose_person(body, orient_level: np.ndarray, pelvis_level: np.ndarray, betas: np.ndarray, R_world: np.ndarray,
                t_world: np.ndarray, body_pose: np.ndarray):
    """SMPL parameters, joints and vertices of a body whose pelvis and orientation are given in the level
    world, expressed in a world ``x = R_world x_level + t_world``."""
    orient = Rotation.from_matrix(R_world @ orient_level).as_rotvec()
    pelvis = R_world @ pelvis_level + t_world
    transl = pelvis - rest_pelvis(body, betas)
    with torch.no_grad():
        out = body.forward(orient, body_pose, betas, transl)
    return orient, transl, out.joints.numpy().astype(np.float64), out.vertices.numpy().astype(np.float64)


def _people_motion(num_frames: int):
    """Two people in the level world: aria01 walks along +x, aria02 stands 0.9 m beside, both facing the cameras."""
    rng = np.random.default_rng(7)
    motion = {}
    for k, name in enumerate(("aria01", "aria02")):
        betas = rng.normal(0, 0.5, 10)
        pose = rng.normal(0, 0.08, (23, 3))
        frames = []
        for f in range(num_frames):
            x = -0.45 + 0.9 * k + (0.15 * f if k == 0 else 0.0)
            yaw = Rotation.from_euler("z", 10.0 * k, degrees=True).as_matrix()
            frames.append((yaw @ SMPL_TO_LEVEL, np.array([x, 0.8 * k, 0.0])))
        motion[name] = dict(betas=betas, pose=pose, frames=frames)
    return motion


def _standing_pelvis(body, betas, pose, orient_level, xy):
    """Pelvis height that puts the lowest vertex on the floor (z = 0)."""
    _, _, _, verts = pose_person(body, orient_level, np.array([xy[0], xy[1], 0.0]), betas, np.eye(3), np.zeros(3), pose)
    return np.array([xy[0], xy[1], -verts[:, 2].min()])


def level_camera(eye, target=(0.0, 0.0, 0.9)):
    R, t = look_at(np.asarray(eye, float), np.asarray(target, float))
    return R, t


def quaternion_wxyz(R: np.ndarray) -> np.ndarray:
    x, y, z, w = Rotation.from_matrix(R).as_quat()
    return np.array([w, x, y, z])


def make_egohumans(root: Path, body, dataset: str = "egohumans", num_frames: int = 6, drop=("aria02", 4),
                   blob_joint: int = 0) -> tuple[Path, CaptureTruth]:
    """An EgoHumans (or Harmony4D) sequence folder; returns it and the truth.

    EgoHumans: ``<root>/01_tagging/001_tagging``, ``colmap_from_aria['aria01'] = 2 * I + shift`` (a scaled
    alignment), ``aria02`` = identity (only the anchor may be used). Harmony4D:
    ``<root>/train/01_hugging/001_hugging`` with ``scale.npy = diag(0.5, 0.5, 0.5, 1)`` and no pickles.
    Each raw frame has a bright 5x5 blob where ``blob_joint`` of aria01 projects through the fisheye.
    """
    seq = root / ("01_tagging/001_tagging" if dataset == "egohumans" else "train/01_hugging/001_hugging")
    work = seq / "colmap" / "workplace"
    work.mkdir(parents=True)
    if dataset == "egohumans":
        align = np.diag([2.0, 2.0, 2.0, 1.0])
        align[:3, 3] = [0.3, -0.2, 0.5]
        transforms = {"aria01": align, "aria02": np.eye(4)}
        with open(work / "colmap_from_aria_transforms.pkl", "wb") as f:
            pickle.dump(transforms, f)
        with open(work / "aria_from_colmap_transforms.pkl", "wb") as f:
            pickle.dump({k: np.linalg.inv(v) for k, v in transforms.items()}, f)
    else:
        np.save(work / "scale.npy", np.diag([0.5, 0.5, 0.5, 1.0]))
        align = np.linalg.inv(np.diag([0.5, 0.5, 0.5, 1.0]))
    scale = float(np.cbrt(np.linalg.det(align[:3, :3])))

    size = (48, 64)
    intrinsics = {"cam01": (40.0, 40.0, 32.0, 24.0, [0.01, 0.0, 0.0, 0.0]),
                  "cam02": (42.0, 41.0, 31.0, 23.5, [0.05, 0.01, 0.0, 0.0])}
    eyes = {"cam01": (0.3, -3.2, 1.4), "cam02": (2.6, -2.0, 1.6)}
    cameras = {}
    cam_lines, img_lines = [], []
    for k, name in enumerate(("cam01", "cam02"), start=1):
        fx, fy, cx, cy, dist = intrinsics[name]
        R_l, t_l = level_camera(eyes[name])
        R_d = R_l @ G.T                       # metric camera in the dataset world
        t_d = t_l - R_d @ g
        # COLMAP stores the camera of the COLMAP world x_c = align x_d; its coordinates are scaled by s.
        A, a = align[:3, :3] / scale, align[:3, 3]
        R_c = R_d @ A.T
        t_c = scale * t_d - R_c @ a
        cameras[name] = dict(K=np.array([[fx, 0, cx], [0, fy, cy], [0, 0, 1.0]]), D=np.array(dist), R=R_d, t=t_d,
                             size=size)
        cam_lines.append(f"{k} OPENCV_FISHEYE {size[1]} {size[0]} {fx} {fy} {cx} {cy} " + " ".join(map(str, dist)))
        q = quaternion_wxyz(R_c)
        img_lines.append(f"{k} {' '.join(f'{v:.15g}' for v in q)} {' '.join(f'{v:.15g}' for v in t_c)} {k} {name}/00001.jpg")
        img_lines.append("")
    cam_lines.append("3 OPENCV_FISHEYE 1408 1408 600 600 704 704 0.1 0 0 0")  # a decoy Aria camera
    img_lines += ["3 1 0 0 0 0 0 0 3 aria01/00001.jpg", ""]
    (work / "cameras.txt").write_text(COLMAP_CAMERAS_HEADER + "\n".join(cam_lines) + "\n")
    (work / "images.txt").write_text(COLMAP_IMAGES_HEADER + "\n".join(img_lines) + "\n")
    floor = np.random.default_rng(3).uniform(-2, 2, (20, 2))
    pts = [(G @ np.array([x, y, 0.0]) + g) * scale for x, y in floor]
    (work / "points3D.txt").write_text(COLMAP_POINTS_HEADER + "".join(
        f"{k + 1} {p[0]:.6f} {p[1]:.6f} {p[2]:.6f} 128 128 128 0.5\n" for k, p in enumerate(pts)))

    motion = _people_motion(num_frames)
    frame_ids = list(range(1, num_frames + 1))
    people = {n: {k: [] for k in ("global_orient", "transl", "joints", "vertices")} for n in motion}
    present = {n: np.ones(num_frames, bool) for n in motion}
    level_joints = {n: [] for n in motion}
    smpl_dir = seq / "processed_data" / "smpl"
    smpl_dir.mkdir(parents=True)
    rng = np.random.default_rng(11)
    for f, frame_id in enumerate(frame_ids):
        record = {}
        for name, m in motion.items():
            orient_l, xy = m["frames"][f]
            pelvis_l = _standing_pelvis(body, m["betas"], m["pose"], orient_l, xy[:2])
            orient, transl, joints, verts = pose_person(body, orient_l, pelvis_l, m["betas"], G, g, m["pose"])
            level_joints[name].append((joints - g) @ G)
            for key, value in (("global_orient", orient), ("transl", transl), ("joints", joints), ("vertices", verts)):
                people[name][key].append(value)
            if drop and name == drop[0] and frame_id == drop[1]:
                present[name][f] = False
                continue
            record[name] = {
                "global_orient": orient, "body_pose": m["pose"].reshape(69), "betas": m["betas"], "transl": transl,
                "vertices": verts, "joints": np.concatenate([joints, joints[:21] + rng.normal(0, 0.01, (21, 3))]),
                "epoch_loss": 0.1,
            }
        np.save(smpl_dir / f"{frame_id:05d}.npy", record, allow_pickle=True)
    people = {n: {k: np.asarray(v) for k, v in d.items()} for n, d in people.items()}
    for name, m in motion.items():
        people[name]["betas"] = m["betas"]
        people[name]["body_pose"] = m["pose"]

    for name, cam in cameras.items():
        folder = seq / "exo" / name / "images"
        folder.mkdir(parents=True)
        rvec, _ = cv2.Rodrigues(cam["R"])
        for f, frame_id in enumerate(frame_ids):
            image = np.full((*size, 3), 30, np.uint8)
            image[:, :, 2] = np.linspace(20, 90, size[1], dtype=np.uint8)[None]  # a gradient, so frames differ by camera
            uv, _ = cv2.fisheye.projectPoints(people["aria01"]["joints"][f][None, blob_joint:blob_joint + 1],
                                              rvec, cam["t"], cam["K"], cam["D"])
            u, v = np.round(uv.reshape(2)).astype(int)
            image[max(v - 2, 0):v + 3, max(u - 2, 0):u + 3] = 255
            cv2.imwrite(str(folder / f"{frame_id:05d}.jpg"), image, [cv2.IMWRITE_JPEG_QUALITY, 100])
    if dataset == "harmony4d":
        for frame_id in frame_ids:
            for sub, value in (("poses2d", {n: np.zeros((45, 2)) for n in motion}),
                               ("bbox", {n: np.array([1.0, 2.0, 30.0, 40.0]) for n in motion})):
                folder = seq / "processed_data" / sub / "cam01"
                folder.mkdir(parents=True, exist_ok=True)
                np.save(folder / f"{frame_id:05d}.npy", value, allow_pickle=True)
    truth = CaptureTruth(frame_ids, people, present, cameras, {n: np.asarray(v) for n, v in level_joints.items()})
    return seq, truth


REC = "recording_20220225_S27_S26_01"


def make_egobody(root: Path, body, frames=range(3, 9), start: int = 4, end: int = 7, omit=("body_idx_0", 6),
                 split: str = "val") -> CaptureTruth:
    """An EgoBody root with one recording (views master and sub_1, 64x36 jpgs); returns the truth.

    The world is the master Kinect colour camera (OpenCV axes: y down, z forward).
    """
    root.mkdir(parents=True, exist_ok=True)
    with open(root / "data_info_release.csv", "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["recording_name", "start_frame", "end_frame", "body_idx_0", "body_idx_1", "body_idx_fpv",
                         "scene_name"])
        writer.writerow([REC, start, end, "0 male", "1 female", "1 female", "seminar_d78"])
    with open(root / "data_splits.csv", "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["train", "val", "test"])
        row = ["recording_20210907_S03_S04_01", "nan", "nan"]
        row[["train", "val", "test"].index(split)] = REC
        writer.writerow(row)
        writer.writerow(["recording_20210907_S03_S04_02", "", ""])  # ragged: NaN-padded columns
    size = (36, 64)
    K = np.array([[50.0, 0, 32.0], [0, 50.0, 18.0], [0, 0, 1]])
    dist = {"master": [0.02, -0.01, 0.001, 0.0, 0.0], "sub_1": [-0.03, 0.0, 0.0, 0.001, 0.0]}
    T_11to12 = np.eye(4)  # sub_1 colour -> master colour
    T_11to12[:3, :3] = Rotation.from_euler("y", -25, degrees=True).as_matrix()
    T_11to12[:3, 3] = [1.2, 0.05, 0.4]
    cameras = {}
    for view in ("master", "sub_1"):
        folder = root / "kinect_cam_params" / f"kinect_{view}"
        folder.mkdir(parents=True)
        (folder / "Color.json").write_text(json.dumps({"f": [50.0, 50.0], "c": [32.0, 18.0],
                                                       "camera_mtx": K.tolist(), "k": dist[view]}))
        E = np.eye(4) if view == "master" else np.linalg.inv(T_11to12)
        cameras[view] = dict(K=K, D=np.array(dist[view]), R=E[:3, :3], t=E[:3, 3], size=size)
    cal = root / "calibrations" / REC / "cal_trans"
    cal.mkdir(parents=True)
    (cal / "kinect_11to12_color.json").write_text(json.dumps({"trans": T_11to12.tolist()}))

    rng = np.random.default_rng(5)
    face_camera = Rotation.from_euler("x", 180, degrees=True).as_matrix()  # SMPL +y up -> camera -y (up)
    people, present = {}, {}
    frame_ids = list(frames)
    for k, (name, role) in enumerate((("body_idx_0", "camera_wearer"), ("body_idx_1", "interactee"))):
        betas, pose = rng.normal(0, 0.5, 10), rng.normal(0, 0.08, (23, 3))
        arrays = {key: [] for key in ("global_orient", "transl", "joints")}
        present[name] = np.ones(len(frame_ids), bool)
        for f, frame_id in enumerate(frame_ids):
            pelvis = np.array([-0.4 + 0.8 * k + 0.02 * f, 0.1, 3.0])
            orient, transl, joints, _ = pose_person(body, face_camera, pelvis, betas, np.eye(3), np.zeros(3), pose)
            for key, value in (("global_orient", orient), ("transl", transl), ("joints", joints)):
                arrays[key].append(value)
            if (name, frame_id) == tuple(omit):
                present[name][f] = False
                continue
            folder = root / f"smpl_{role}_{split}" / REC / name / "results" / f"frame_{frame_id:05d}"
            folder.mkdir(parents=True)
            with open(folder / "000.pkl", "wb") as fh:
                pickle.dump({"transl": transl[None], "global_orient": orient[None], "body_pose": pose.reshape(1, 69),
                             "betas": betas[None]}, fh)
        people[name] = {key: np.asarray(v) for key, v in arrays.items()} | {"betas": betas, "body_pose": pose}
    for view in ("master", "sub_1"):
        folder = root / "kinect_color" / REC / view
        folder.mkdir(parents=True)
        for frame_id in frame_ids:
            cv2.imwrite(str(folder / f"frame_{frame_id:05d}.jpg"), np.full((*size, 3), 40 + frame_id, np.uint8))
    return CaptureTruth(frame_ids, people, present, cameras)


def make_ava(root: Path, with_frames: bool = True) -> Path:
    """An AVA root: a 3-row ``ava_val_v2.2.csv``, midframes 0902..0905 of one video, and a 4-frame clip npz."""
    vid = "-5KQ66BBWC4"
    root.mkdir(parents=True, exist_ok=True)
    with open(root / "ava_val_v2.2.csv", "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow([vid, "0902", "0.077", "0.151", "0.283", "0.811", "80", "1"])
        writer.writerow([vid, "0902", "0.332", "0.194", "0.481", "0.891", "12", "0"])
        writer.writerow([vid, "0903", "0.079", "0.149", "0.290", "0.800", "80", "1"])
    names = [f"val/midframes/{vid}/{sec:04d}.jpg" for sec in range(902, 906)]
    if with_frames:
        for name in names:
            (root / name).parent.mkdir(parents=True, exist_ok=True)
            cv2.imwrite(str(root / name), np.zeros((36, 64, 3), np.uint8))
    rng = np.random.default_rng(2)
    keypoints = np.concatenate([rng.uniform(5, 60, (4, 25, 2)), rng.uniform(0.6, 1.0, (4, 25, 1))], axis=-1)
    clip = root / "multishot" / "ava_clip_000.npz"
    clip.parent.mkdir(parents=True, exist_ok=True)
    np.savez(clip, imgname=np.array(names), shot=np.array([0, 0, 1, 1]), body_keypoints=keypoints,
             valid=np.array([1, 1, 1, 1]), pred_aa=np.zeros((4, 72)), pred_betas=np.zeros((4, 10)),
             cam_trans=np.zeros((4, 3)), pred_torso=np.zeros((4, 4, 2)), center=np.zeros((4, 2)),
             scale=np.ones(4), width=np.full(4, 64), height=np.full(4, 36), seqname=np.array([vid] * 4))
    return clip


SITCOM = "TBBT-big_living_room"


def make_sitcoms(root: Path) -> dict:
    """A sitcom root: two images across a cut, two humans each, human 1 of A is human 0 of B."""
    rng = np.random.default_rng(4)
    images = ["TBBT_S08E07_00000120.jpg", "TBBT_S08E07_00000131.jpg"]
    humans = {img: [{"openpose_keypoints": np.concatenate([rng.uniform(0, 60, (25, 2)), rng.uniform(0.6, 1, (25, 1))],
                                                          axis=-1).reshape(-1).tolist()} for _ in range(2)]
              for img in images}
    humans[images[1]][0]["smpl"] = {"camera_translation": [0, 0, 3], "betas": [0.0] * 10, "global_orient": [0, 0, 0],
                                    "body_pose": [0.0] * 69, "colmap_rescale": 1.0}
    for sub, data in (("human_data", humans), ("human_pairs", [[images[0], 1, images[1], 0]])):
        (root / sub).mkdir(parents=True, exist_ok=True)
        (root / sub / f"{SITCOM}.json").write_text(json.dumps(data))
    K = [[50.0, 0, 32.0], [0, 50.0, 24.0], [0, 0, 1]]
    poses = [np.eye(4), np.eye(4)]
    poses[1][:3, :3] = Rotation.from_euler("y", 30, degrees=True).as_matrix()
    poses[1][:3, 3] = [1.5, 0.0, 0.4]
    folder = root / "sparse_reconstruction_and_nerf_data" / SITCOM
    folder.mkdir(parents=True)
    (folder / "cameras.json").write_text(json.dumps({"bbox": [[-1, -1, -1], [1, 1, 1]], "scale_factor": 1.0,
                                                     "point_cloud_transform": np.eye(4).tolist(), "frames": [
        {"image_name": img, "intrinsics": K, "camtoworld": pose.tolist()} for img, pose in zip(images, poses)]}))
    return {"images": images, "humans": humans, "camtoworld": poses}
