"""Every frame's camera: ``cameras.npz`` and COLMAP's text model (``cameras.txt``, ``images.txt``, ``points3D.txt``).

``cameras.npz`` fields (``T`` frames; conventions of :mod:`multithumbs.conventions`: OpenCV pinhole,
world-to-camera ``x_cam = R x_world + t``):

==================  ==============  ===================================================================
field               shape           meaning
==================  ==============  ===================================================================
``K``               (T, 3, 3)       intrinsics in pixels (pixel centres at integer coordinates)
``R``, ``t``        (T, 3, 3), (T, 3)  world-to-camera rotation and translation
``centres``         (T, 3)          camera centres ``-R^T t`` in the world
``camera_to_world`` (T, 4, 4)       inverse extrinsics as homogeneous matrices
``frames``          (T,)            video frame index
``shot``            (T,)            shot index of every frame
``cut_frames``      (C,)            first frame of each new shot
``fps``, ``image_size``  (), (2,)   frames per second; ``(H, W)``
``world_up``        (3,)            the world's estimated up direction
==================  ==============  ===================================================================

COLMAP text model: one ``PINHOLE`` camera per distinct intrinsics, one image per video frame named
``frame_XXXXXX.png`` (extract the video's frames under those names to use it, e.g. ``ffmpeg -i video.mp4
-start_number 0 frame_%06d.png``), COLMAP's pixel-centre convention (``cx + 0.5``, ``cy + 0.5``) and its
``QW QX QY QZ TX TY TZ`` world-to-camera poses. Scene points (world frame, one array per cut) become
``points3D.txt`` with a track in the cut's two boundary images where they project inside the image.
"""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np
from scipy.spatial.transform import Rotation

from multithumbs.errors import InputError
from multithumbs.export.files import write_text_atomic
from multithumbs.export.posed import camera_centres, shot_index
from multithumbs.io import save_npz_atomic
from multithumbs.types import WorldResult

COLMAP_FILES = ("cameras.txt", "images.txt", "points3D.txt")


def frame_image_name(frame: int) -> str:
    """The image name of a video frame in the COLMAP model."""
    return f"frame_{int(frame):06d}.png"


def camera_arrays(result: WorldResult, up: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """The arrays of ``cameras.npz`` (module docstring)."""
    t = result.num_frames
    centres = camera_centres(result)
    to_world = np.tile(np.eye(4), (t, 1, 1))
    to_world[:, :3, :3] = np.swapaxes(result.R, 1, 2)
    to_world[:, :3, 3] = centres
    arrays = {"K": np.asarray(result.K, np.float64), "R": np.asarray(result.R, np.float64),
              "t": np.asarray(result.t, np.float64), "centres": centres, "camera_to_world": to_world,
              "frames": np.arange(t, dtype=np.int64), "shot": shot_index(result).astype(np.int64),
              "cut_frames": np.asarray(result.cut_frames, np.int64), "fps": np.float64(result.fps),
              "image_size": np.asarray(result.image_size, np.int64)}
    if up is not None:
        arrays["world_up"] = np.asarray(up, np.float64)
    return arrays


def write_cameras_npz(path: str | Path, result: WorldResult, up: np.ndarray | None = None) -> Path:
    """Write ``cameras.npz`` (module docstring) atomically."""
    return save_npz_atomic(path, camera_arrays(result, up))


def check_scene_points(scene_points: Sequence[np.ndarray] | None, num_cuts: int) -> list[np.ndarray]:
    """Validate optional scene points: one ``(N, 3)`` finite world-frame array per cut (or none at all)."""
    if scene_points is None or len(scene_points) == 0:
        return []
    points = [np.asarray(p, dtype=np.float64) for p in scene_points]
    if len(points) != num_cuts:
        raise InputError(f"scene_points: expected one array per cut ({num_cuts}), got {len(points)}")
    for k, p in enumerate(points):
        if p.ndim != 2 or p.shape[1] != 3:
            raise InputError(f"scene_points[{k}]: expected shape (N, 3), got {p.shape}")
        if not np.all(np.isfinite(p)):
            raise InputError(f"scene_points[{k}]: contains non-finite values")
    return points


def project_to_frame(result: WorldResult, frame: int, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pixels ``(N, 2)`` of world ``points (N, 3)`` in ``frame`` and ``(N,)`` bool: in front and inside the image."""
    cam = points @ result.R[frame].T + result.t[frame]
    z = cam[:, 2]
    uv = (cam / np.where(z > 1e-9, z, 1.0)[:, None]) @ result.K[frame].T
    h, w = result.image_size
    inside = (z > 1e-9) & (uv[:, 0] > -0.5) & (uv[:, 0] < w - 0.5) & (uv[:, 1] > -0.5) & (uv[:, 1] < h - 0.5)
    return uv[:, :2], inside


def colmap_text(result: WorldResult, scene_points: Sequence[np.ndarray] | None = None,
                point_colors: Sequence[np.ndarray] | None = None) -> dict[str, str]:
    """The three files of a COLMAP text model of the result's cameras and the scene points.

    Args:
        result: the reconstruction.
        scene_points: optional world-frame points, one ``(N_k, 3)`` array per cut.
        point_colors: optional ``(N_k, 3)`` uint8 RGB per cut (grey when None).
    Returns:
        file name -> contents.
    """
    points = check_scene_points(scene_points, int(result.cut_frames.size))
    if point_colors is not None and [len(c) for c in point_colors] != [len(p) for p in points]:
        raise InputError("point_colors: need one colour per scene point of every cut")
    h, w = result.image_size
    flat_K = np.round(np.asarray(result.K, np.float64).reshape(-1, 9), 9)
    unique_K, camera_of_frame = np.unique(flat_K, axis=0, return_inverse=True)
    camera_of_frame = camera_of_frame.reshape(-1)
    cam_lines = ["# Camera list with one line of data per camera:",
                 "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]",
                 f"# Number of cameras: {len(unique_K)}"]
    for i, k in enumerate(unique_K.reshape(-1, 3, 3)):
        # COLMAP puts pixel centres at +0.5 (conventions.py).
        cam_lines.append(f"{i + 1} PINHOLE {w} {h} {k[0, 0]:.9g} {k[1, 1]:.9g} {k[0, 2] + 0.5:.9g} {k[1, 2] + 0.5:.9g}")

    # Observations of scene points in the two boundary images of their cut.
    observations: dict[int, list[tuple[float, float, int]]] = {}
    tracks: list[list[tuple[int, int]]] = []
    all_points, colours = [], []
    next_id = 1
    for k, pts in enumerate(points):
        cut = int(result.cut_frames[k])
        ids = np.arange(next_id, next_id + len(pts))
        next_id += len(pts)
        point_tracks: list[list[tuple[int, int]]] = [[] for _ in range(len(pts))]
        for frame in (cut - 1, cut):
            uv, inside = project_to_frame(result, frame, pts)
            obs = observations.setdefault(frame, [])
            for i in np.nonzero(inside)[0]:
                point_tracks[i].append((frame + 1, len(obs)))
                obs.append((uv[i, 0] + 0.5, uv[i, 1] + 0.5, int(ids[i])))
        tracks.extend(point_tracks)
        all_points.append(pts)
        colours.append(np.full((len(pts), 3), 128, np.uint8) if point_colors is None
                       else np.asarray(point_colors[k], np.uint8).reshape(-1, 3))

    quat = Rotation.from_matrix(np.asarray(result.R, np.float64)).as_quat()  # x, y, z, w
    num_obs = sum(len(v) for v in observations.values())
    img_lines = ["# Image list with two lines of data per image:",
                 "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME",
                 "#   POINTS2D[] as (X, Y, POINT3D_ID)",
                 f"# Number of images: {result.num_frames}, mean observations per image: "
                 f"{num_obs / max(result.num_frames, 1):.3f}"]
    for f in range(result.num_frames):
        x, y, z, qw = quat[f]
        tx, ty, tz = result.t[f]
        img_lines.append(f"{f + 1} {qw:.12g} {x:.12g} {y:.12g} {z:.12g} {tx:.12g} {ty:.12g} {tz:.12g} "
                         f"{camera_of_frame[f] + 1} {frame_image_name(f)}")
        img_lines.append(" ".join(f"{u:.6f} {v:.6f} {pid}" for u, v, pid in observations.get(f, [])))

    xyz = np.concatenate(all_points) if all_points else np.zeros((0, 3))
    rgb = np.concatenate(colours) if colours else np.zeros((0, 3), np.uint8)
    pt_lines = ["# 3D point list with one line of data per point:",
                "#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)",
                f"# Number of points: {len(xyz)}"]
    for i, (p, c, track) in enumerate(zip(xyz, rgb, tracks)):
        pt_lines.append(f"{i + 1} {p[0]:.9g} {p[1]:.9g} {p[2]:.9g} {c[0]} {c[1]} {c[2]} 0 "
                        + " ".join(f"{img} {idx}" for img, idx in track))
    return {"cameras.txt": "\n".join(cam_lines) + "\n", "images.txt": "\n".join(img_lines) + "\n",
            "points3D.txt": "\n".join(pt_lines) + "\n"}


def write_colmap_text(out_dir: str | Path, result: WorldResult, scene_points: Sequence[np.ndarray] | None = None,
                      point_colors: Sequence[np.ndarray] | None = None) -> dict[str, Path]:
    """Write the COLMAP text model (:func:`colmap_text`) into ``out_dir`` (created), each file atomically."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    return {name: write_text_atomic(out / name, text)
            for name, text in colmap_text(result, scene_points, point_colors).items()}
