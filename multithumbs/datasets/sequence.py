"""What every multi-view capture loader yields: cameras, frames on demand, and world-frame people.

A :class:`MultiViewSequence` is one synchronised capture: static calibrated cameras, the dataset's frame
ids (the same id is the same instant in every camera), and the people the dataset annotates with SMPL.
Frames are read from disk only when asked for; ground truth is read for the frames asked for. The
world frame is the dataset's own metric world (EgoHumans/Harmony4D: the alignment's world; EgoBody:
the master Kinect colour camera); :mod:`multithumbs.datasets.benchmark` levels it to the project's
``+z`` up, floor at ``z = 0`` world when it builds a clip.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Sequence

import cv2
import numpy as np

from multithumbs.conventions import NUM_BETAS, NUM_BODY_JOINTS, NUM_JOINTS
from multithumbs.datasets.cameras import Camera
from multithumbs.errors import InputError


@dataclass(frozen=True)
class PeopleSeries:
    """SMPL ground truth of ``P`` people over ``T`` frames in the dataset's metric world frame.

    Attributes:
        names: ``(P,)`` the dataset's person names (``"aria01"``, ``"body_idx_0"``...).
        frame_ids: ``(T,)`` the dataset's frame ids.
        global_orient: ``(P, T, 3)`` axis-angle, world frame.
        body_pose: ``(P, T, 23, 3)`` axis-angle.
        betas: ``(P, T, 10)`` shape as stored per frame (datasets repeat it or refit it per frame).
        transl: ``(P, T, 3)`` SMPL translation, world frame (metres).
        joints: ``(P, T, 24, 3)`` SMPL joints in the world frame (metres): the dataset's stored joints
            where it stores them, else the body model's.
        valid: ``(P, T)`` bool, the person has ground truth at that frame (a gap is ``False``).
        genders: ``(P,)`` ``"neutral"``, ``"male"`` or ``"female"``: the body model the dataset fitted.
        vertices: ``(P, T, V, 3)`` float32 world mesh vertices where the dataset stores them, else None.
    """

    names: tuple[str, ...]
    frame_ids: np.ndarray
    global_orient: np.ndarray
    body_pose: np.ndarray
    betas: np.ndarray
    transl: np.ndarray
    joints: np.ndarray
    valid: np.ndarray
    genders: tuple[str, ...]
    vertices: np.ndarray | None = None

    def __post_init__(self) -> None:
        p, t = len(self.names), len(self.frame_ids)
        shapes = {"global_orient": (p, t, 3), "body_pose": (p, t, NUM_BODY_JOINTS, 3),
                  "betas": (p, t, NUM_BETAS), "transl": (p, t, 3), "joints": (p, t, NUM_JOINTS, 3),
                  "valid": (p, t)}
        for name, shape in shapes.items():
            value = np.asarray(getattr(self, name))
            if value.shape != shape:
                raise InputError(f"PeopleSeries.{name}: expected shape {shape}, got {value.shape}")
        if len(self.genders) != p:
            raise InputError(f"PeopleSeries.genders: expected {p} entries, got {len(self.genders)}")
        if self.vertices is not None and self.vertices.shape[:2] != (p, t):
            raise InputError(f"PeopleSeries.vertices: expected ({p}, {t}, V, 3), got {self.vertices.shape}")


@dataclass(frozen=True)
class MultiViewSequence:
    """One synchronised multi-view capture with SMPL ground truth.

    Attributes:
        dataset: ``"egohumans"``, ``"harmony4d"`` or ``"egobody"``.
        name: the sequence's name relative to the data root (``"01_tagging/001_tagging"``,
            ``"train/01_hugging/001_hugging"``, ``"recording_20220225_S27_S26_01"``).
        root: the sequence's folder.
        cameras: the usable static cameras, in the dataset's order.
        frame_ids: ``(T,)`` int, the dataset's ids of the usable frames, increasing; the sequence's
            frame ``i`` (0-based, our convention) is dataset frame ``frame_ids[i]``.
        fps: frames per second (the dataset's documented rate; a spec may override it).
        people: names of the people the dataset annotates in this sequence.
        alignment: how the world frame was made metric (``"colmap+aria:aria01"``, ``"scale.npy"``,
            ``"kinect-master"``).
        notes: facts a user should know about this sequence (left-out cameras, withheld data...).
        image_path: ``(camera name, dataset frame id, undistorted) -> (path, already_undistorted)``.
        read_people: ``(frame_ids, names, with_vertices) -> PeopleSeries``.
    """

    dataset: str
    name: str
    root: Path
    cameras: tuple[Camera, ...]
    frame_ids: np.ndarray
    fps: float
    people: tuple[str, ...]
    alignment: str
    notes: tuple[str, ...] = ()
    image_path: Callable[[str, int], tuple[Path, bool]] = field(default=None, repr=False, compare=False)  # type: ignore[assignment]
    read_people: Callable[[np.ndarray, Sequence[str], bool], PeopleSeries] = field(
        default=None, repr=False, compare=False)  # type: ignore[assignment]

    @property
    def num_frames(self) -> int:
        return int(len(self.frame_ids))

    @property
    def camera_names(self) -> tuple[str, ...]:
        return tuple(c.name for c in self.cameras)

    def camera(self, name: str) -> Camera:
        """The camera called ``name`` (InputError listing the cameras if there is none)."""
        for camera in self.cameras:
            if camera.name == name:
                return camera
        raise InputError(f"{self.dataset} {self.name}: no camera {name!r} (cameras: {', '.join(self.camera_names)})")

    def check_indices(self, indices: Sequence[int] | np.ndarray) -> np.ndarray:
        """``indices`` as an int array, each a valid 0-based frame of this sequence."""
        idx = np.asarray(indices, dtype=np.int64).reshape(-1)
        bad = idx[(idx < 0) | (idx >= self.num_frames)]
        if bad.size:
            raise InputError(f"{self.dataset} {self.name}: frame {int(bad[0])} is outside [0, {self.num_frames}) "
                             f"(the sequence has {self.num_frames} usable frames)")
        return idx

    def frame(self, camera: str, index: int, undistort: bool = True) -> np.ndarray:
        """RGB ``(H, W, 3)`` uint8 of ``camera`` at 0-based frame ``index``, undistorted to the pinhole ``K``
        unless ``undistort=False`` (then the raw image)."""
        cam = self.camera(camera)
        (i,) = self.check_indices([index])
        path, already = self.image_path(camera, int(self.frame_ids[i]), undistort)
        image = read_rgb(path)
        if image.shape[:2] != cam.image_size:
            raise InputError(f"{path}: image is {image.shape[1]}x{image.shape[0]}, but camera {camera} is calibrated "
                             f"for {cam.image_size[1]}x{cam.image_size[0]}")
        return cam.undistort_image(image) if undistort and not already else image

    def ground_truth(self, indices: Sequence[int] | np.ndarray | None = None,
                     people: Sequence[str] | None = None, with_vertices: bool = False) -> PeopleSeries:
        """World-frame SMPL ground truth of ``people`` (default: all) at 0-based frames ``indices`` (default: all)."""
        idx = np.arange(self.num_frames) if indices is None else self.check_indices(indices)
        names = tuple(self.people if people is None else people)
        unknown = [n for n in names if n not in self.people]
        if unknown:
            raise InputError(f"{self.dataset} {self.name}: no person {unknown[0]!r} (people: {', '.join(self.people)})")
        return self.read_people(self.frame_ids[idx], names, with_vertices)

    def describe(self) -> dict:
        """JSON-ready summary: cameras, people, frames (what ``multithumbs dataset list`` prints)."""
        return {
            "dataset": self.dataset, "sequence": self.name, "num_frames": self.num_frames,
            "frame_ids": [int(self.frame_ids[0]), int(self.frame_ids[-1])] if self.num_frames else [],
            "fps": self.fps, "people": list(self.people), "alignment": self.alignment,
            "cameras": [{"name": c.name, "model": c.model, "width": c.image_size[1], "height": c.image_size[0],
                         "centre": [round(float(x), 4) for x in c.centre]} for c in self.cameras],
            "notes": list(self.notes),
        }


def read_rgb(path: str | Path) -> np.ndarray:
    """An image file as RGB ``(H, W, 3)`` uint8 (InputError naming the file when missing or unreadable)."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: frame image not found")
    image = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if image is None:
        raise InputError(f"{path}: not an image OpenCV can read")
    return cv2.cvtColor(image, cv2.COLOR_BGR2RGB)


def require_files(base: Path, relative: Sequence[str], what: str) -> None:
    """Raise InputError naming the first of ``relative`` (paths under ``base``) that is missing."""
    for rel in relative:
        if not (base / rel).exists():
            raise InputError(f"{base / rel}: missing ({what})")


def smpl_array(value, shape: tuple[int, ...], where: str) -> np.ndarray:
    """A stored SMPL field as a float64 array of ``shape`` (leading singleton axes dropped, as datasets store ``(1, k)``)."""
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(f"{where}: not numeric") from None
    if arr.size != int(np.prod(shape)):
        raise InputError(f"{where}: expected {int(np.prod(shape))} values {shape}, got shape {arr.shape}")
    arr = arr.reshape(shape)
    if not np.all(np.isfinite(arr)):
        raise InputError(f"{where}: holds non-finite values")
    return arr


def read_betas(value, where: str) -> np.ndarray:
    """The first 10 shape coefficients of a stored ``betas`` (``(10,)``, ``(1, 10)`` or more components)."""
    arr = np.asarray(value, dtype=np.float64).reshape(-1) if np.size(value) else np.zeros(0)
    if arr.size < NUM_BETAS:
        raise InputError(f"{where}: expected at least {NUM_BETAS} shape coefficients, got {arr.size}")
    return smpl_array(arr[:NUM_BETAS], (NUM_BETAS,), where)


__all__ = ["MultiViewSequence", "PeopleSeries", "read_betas", "read_rgb", "require_files", "smpl_array"]
