"""Writing a synthetic scene to disk: ``video.mp4``, ``ground_truth.npz``, ``contact_sheet.png``."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from multithumbs.errors import InputError
from multithumbs.io import make_output_dir, publish, save_ground_truth

if TYPE_CHECKING:  # the writers import OpenCV and the scene themselves: preparing a folder needs neither
    from multithumbs.synth.scene import SyntheticVideo

OUTPUT_NAMES = ("video.mp4", "ground_truth.npz", "contact_sheet.png")


def write_video(path: str | Path, frames: np.ndarray, fps: float) -> Path:
    """Encode ``frames (T, H, W, 3)`` RGB uint8 as MPEG-4 (atomic rename when complete)."""
    import cv2

    path = Path(path)
    t, h, w, _ = frames.shape
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=path.suffix, dir=path.parent)
    os.close(fd)
    try:
        writer = cv2.VideoWriter(tmp, cv2.VideoWriter_fourcc(*"mp4v"), float(fps), (w, h))
        if not writer.isOpened():
            raise InputError(f"{path}: OpenCV cannot open an MPEG-4 writer here")
        for frame in frames:
            writer.write(cv2.cvtColor(frame, cv2.COLOR_RGB2BGR))
        writer.release()
        publish(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def write_image(path: str | Path, rgb: np.ndarray) -> Path:
    """Write an RGB image (PNG by the suffix) atomically."""
    import cv2

    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=path.suffix, dir=path.parent)
    os.close(fd)
    try:
        if not cv2.imwrite(tmp, cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR)):
            raise InputError(f"{path}: could not encode the image")
        publish(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def contact_sheet(video: SyntheticVideo, per_shot: int = 3, tile_width: int = 320) -> np.ndarray:
    """A grid of frames, one row per shot: the shot's first, middle and last frames (boundary frames included).

    Each tile is labelled with its shot and frame; the last frame before a cut and the first after it get
    a red and a blue border so the pair across the cut is easy to find.
    """
    import cv2

    from multithumbs.viz.labels import draw_label

    frames = video.frames
    t, h, w, _ = frames.shape
    scale = tile_width / w
    tile_h = int(round(h * scale))
    edges = [0, *video.scene.cut_frames.tolist(), t]
    rows = []
    for shot, (a, b) in enumerate(zip(edges[:-1], edges[1:])):
        picks = np.unique(np.linspace(a, b - 1, per_shot).round().astype(int))
        tiles = []
        for f in picks:
            tile = cv2.resize(frames[f], (tile_width, tile_h), interpolation=cv2.INTER_AREA)
            border = (220, 30, 30) if f == b - 1 and b < t else (30, 90, 230) if f == a and a > 0 else (255, 255, 255)
            tile = cv2.copyMakeBorder(tile, 3, 3, 3, 3, cv2.BORDER_CONSTANT, value=border)
            draw_label(tile, f"shot {shot}  frame {f}", (8, 20), 0.5)
            tiles.append(tile)
        while len(tiles) < per_shot:
            tiles.append(np.full_like(tiles[0], 255))
        rows.append(np.concatenate(tiles, axis=1))
    return np.concatenate(rows, axis=0)


def prepare_output_dir(out_dir: str | Path, overwrite: bool = False, names: tuple[str, ...] = OUTPUT_NAMES) -> Path:
    """Create ``out_dir`` if needed; refuse to replace existing outputs (files ``names``) unless ``overwrite``."""
    out = make_output_dir(out_dir)
    existing = [n for n in names if (out / n).exists()]
    if existing and not overwrite:
        raise InputError(f"{out / existing[0]}: already exists (pass --overwrite to replace it)")
    return out


def write_synthetic(out_dir: str | Path, video: SyntheticVideo) -> dict[str, Path]:
    """Write the video, the ground truth (with masks and boundary depth) and the contact sheet."""
    out = Path(out_dir)
    scene = video.scene
    extras = {
        "instance": video.instance,
        "boundary_depth": video.boundary_depth.astype(np.float32),
        "rig_K": scene.cameras.K, "rig_R": scene.cameras.R, "rig_t": scene.cameras.t,
    }
    return {
        "video": write_video(out / "video.mp4", video.frames, scene.config.fps),
        "ground_truth": save_ground_truth(out / "ground_truth.npz", video.truth, extras),
        "contact_sheet": write_image(out / "contact_sheet.png", contact_sheet(video)),
    }
