"""Reading video files: probing and decoding frames on demand (frames are never copied into the store).

Frames are RGB ``uint8`` arrays ``(H, W, 3)``, indexed from 0 at the video's native frame rate
(:mod:`multithumbs.conventions`). Every failure is an :class:`~multithumbs.errors.InputError` naming the
file: a missing file, a file OpenCV cannot decode, a video of zero frames, a frame index beyond the end.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator, Sequence

import cv2
import numpy as np

from multithumbs.errors import InputError

# FFmpeg prints its own complaints about broken files to stderr; ours is the one-line InputError.
os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")


@dataclass(frozen=True)
class VideoInfo:
    """What a video file holds.

    Attributes:
        path: the file.
        num_frames: frames that decode (counted, not taken from the container's header).
        fps: frames per second from the container (25 when the container does not say).
        width: frame width in pixels.
        height: frame height in pixels.
    """

    path: Path
    num_frames: int
    fps: float
    width: int
    height: int

    @property
    def image_size(self) -> tuple[int, int]:
        """``(H, W)``."""
        return self.height, self.width


def _open(path: Path) -> cv2.VideoCapture:
    if not path.exists():
        raise InputError(f"{path}: no such video file")
    if not path.is_file():
        raise InputError(f"{path}: not a file")
    if path.stat().st_size == 0:
        raise InputError(f"{path}: the file is empty")
    capture = cv2.VideoCapture(str(path))
    if not capture.isOpened():
        raise InputError(f"{path}: not a video OpenCV can read")
    return capture


def check_intrinsics(values: Sequence[float]) -> list[float]:
    """``[fx, fy, cx, cy]`` as floats, or :class:`InputError` unless the focal lengths are positive and all
    four finite (kept here, beside the video, so the CLI checks it without importing the flows)."""
    values = [float(v) for v in values]
    if len(values) != 4 or not all(np.isfinite(values)) or values[0] <= 0 or values[1] <= 0:
        raise InputError(f"intrinsics: expected positive fx, fy and finite cx, cy, got {values}")
    return values


def probe_video(path: str | Path) -> VideoInfo:
    """Open ``path`` and count its decodable frames (the header's count is unreliable for edited video)."""
    path = Path(path)
    capture = _open(path)
    try:
        fps = float(capture.get(cv2.CAP_PROP_FPS)) or 25.0
        width = int(capture.get(cv2.CAP_PROP_FRAME_WIDTH))
        height = int(capture.get(cv2.CAP_PROP_FRAME_HEIGHT))
        count = 0
        while capture.grab():
            count += 1
    finally:
        capture.release()
    if count == 0:
        raise InputError(f"{path}: the video has no frames")
    if not np.isfinite(fps) or fps <= 0:
        fps = 25.0
    return VideoInfo(path, count, fps, width, height)


def iter_frames(path: str | Path, start: int = 0, stop: int | None = None) -> Iterator[np.ndarray]:
    """Yield RGB frames ``(H, W, 3)`` uint8 of ``[start, stop)`` in order (decoding sequentially)."""
    path = Path(path)
    capture = _open(path)
    try:
        index = 0
        while stop is None or index < stop:
            if index < start:
                if not capture.grab():
                    return
            else:
                ok, frame = capture.read()
                if not ok:
                    return
                yield cv2.cvtColor(frame, cv2.COLOR_BGR2RGB)
            index += 1
    finally:
        capture.release()


def read_frames(path: str | Path, indices: Sequence[int] | None = None) -> np.ndarray:
    """RGB frames ``(N, H, W, 3)`` uint8 at ``indices`` (all frames when None), in the order asked.

    Decodes sequentially up to the largest index (seeking is inexact in many codecs).
    """
    path = Path(path)
    if indices is None:
        frames = list(iter_frames(path))
        if not frames:
            raise InputError(f"{path}: the video has no frames")
        return np.stack(frames)
    wanted = np.asarray(indices, dtype=int).reshape(-1)
    if wanted.size == 0:
        raise InputError(f"{path}: no frame indices asked for")
    if wanted.min() < 0:
        raise InputError(f"{path}: negative frame index {int(wanted.min())}")
    targets = set(wanted.tolist())
    found: dict[int, np.ndarray] = {}
    decoded = 0
    for index, frame in enumerate(iter_frames(path, 0, int(wanted.max()) + 1)):
        decoded = index + 1
        if index in targets:
            found[index] = frame
    if len(found) < len(targets):
        missing = min(targets - set(found))
        raise InputError(f"{path}: frame {missing} is beyond the end of the video ({decoded} frames)")
    return np.stack([found[i] for i in wanted.tolist()])
