"""Files users hold: a :class:`WorldResult` or :class:`GroundTruth` as one ``.npz``.

Both share the world fields at the top level of the archive, so a ground-truth file is also a valid
result (``multithumbs eval GT GT`` scores zero error). Ground-truth extras are prefixed ``gt_``,
diagnostics ``diag_``; free-form metadata is JSON in ``metadata_json``. Writes are atomic: a reader
never sees a half-written file.
"""

from __future__ import annotations

import json
import os
import tempfile
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from multithumbs.errors import InputError
from multithumbs.types import GroundTruth, WorldResult

_WORLD_ARRAYS = ("person_ids", "global_orient", "body_pose", "betas", "transl", "valid", "K", "R", "t",
                 "cut_frames", "id_map")
_FORMAT = "multithumbs.world/1"


def _world_to_arrays(world: WorldResult) -> dict[str, np.ndarray]:
    arrays = {name: getattr(world, name) for name in _WORLD_ARRAYS}
    arrays["fps"] = np.float64(world.fps)
    arrays["image_size"] = np.asarray(world.image_size, dtype=np.int64)
    if world.keypoints2d is not None:
        arrays["keypoints2d"] = world.keypoints2d
    arrays.update({f"diag_{k}": np.asarray(v) for k, v in world.diagnostics.items()})
    return arrays


def publish(tmp: str | Path, path: str | Path) -> Path:
    """Move a finished temporary file onto ``path`` atomically, with the usual permissions (0666 & ~umask)."""
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)
    os.replace(tmp, path)
    return Path(path)


def save_npz_atomic(path: str | Path, arrays: dict[str, Any], compress: bool = True) -> Path:
    """Write ``arrays`` to ``path`` through a temporary file in the same folder and an atomic rename."""
    path = Path(path)
    if not path.parent.is_dir():
        raise InputError(f"{path.parent}: output folder does not exist")
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            (np.savez_compressed if compress else np.savez)(fh, **arrays)
        publish(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def save_result(path: str | Path, result: WorldResult, metadata: dict[str, Any] | None = None) -> Path:
    """Save a reconstruction as ``.npz`` (atomic)."""
    arrays = _world_to_arrays(result)
    arrays["format"] = np.array(_FORMAT)
    arrays["metadata_json"] = np.array(json.dumps(metadata or {}, sort_keys=True))
    return save_npz_atomic(path, arrays)


def save_ground_truth(path: str | Path, truth: GroundTruth, extras: dict[str, np.ndarray] | None = None) -> Path:
    """Save ground truth as ``.npz`` (atomic); ``extras`` are stored with the ``gt_`` prefix."""
    arrays = _world_to_arrays(truth.world)
    arrays["format"] = np.array(_FORMAT)
    arrays["metadata_json"] = np.array(json.dumps(truth.metadata, sort_keys=True))
    arrays.update(gt_bboxes=truth.bboxes, gt_visible=truth.visible, gt_camera_ids=truth.camera_ids)
    arrays.update({f"gt_{k}": v for k, v in (extras or {}).items()})
    return save_npz_atomic(path, arrays)


def _open(path: str | Path) -> dict[str, np.ndarray]:
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: no such file")
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {k: data[k] for k in data.files}
    except (OSError, ValueError, zipfile.BadZipFile, EOFError) as exc:
        raise InputError(f"{path}: not a readable .npz file ({exc.__class__.__name__})") from None
    if str(arrays.get("format", "")) != _FORMAT:
        raise InputError(f"{path}: not a Multi-THuMBS result or ground-truth file (format field missing)")
    return arrays


def _world_from_arrays(path: Path, arrays: dict[str, np.ndarray]) -> WorldResult:
    missing = [k for k in (*_WORLD_ARRAYS, "fps", "image_size") if k not in arrays]
    if missing:
        raise InputError(f"{path}: missing field {missing[0]!r}")
    return WorldResult(
        **{k: arrays[k] for k in _WORLD_ARRAYS},
        fps=float(arrays["fps"]), image_size=tuple(int(s) for s in arrays["image_size"]),
        keypoints2d=arrays.get("keypoints2d"),
        diagnostics={k[5:]: v for k, v in arrays.items() if k.startswith("diag_")},
    )


def load_result(path: str | Path) -> WorldResult:
    """Load a result (or the world part of a ground-truth file)."""
    return _world_from_arrays(Path(path), _open(path))


def load_ground_truth(path: str | Path) -> tuple[GroundTruth, dict[str, np.ndarray]]:
    """Load ground truth and its extras (without the ``gt_`` prefix)."""
    arrays = _open(path)
    for key in ("gt_bboxes", "gt_visible", "gt_camera_ids"):
        if key not in arrays:
            raise InputError(f"{path}: not a ground-truth file (missing field {key!r})")
    truth = GroundTruth(_world_from_arrays(Path(path), arrays), arrays["gt_bboxes"], arrays["gt_visible"],
                        arrays["gt_camera_ids"], json.loads(str(arrays["metadata_json"])))
    extras = {k[3:]: v for k, v in arrays.items()
              if k.startswith("gt_") and k not in ("gt_bboxes", "gt_visible", "gt_camera_ids")}
    return truth, extras


def read_json(path: str | Path) -> Any:
    """A JSON file's content; :class:`InputError` naming the file when it is missing or not JSON."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: missing")
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError) as error:
        raise InputError(f"{path}: not readable JSON ({error})") from None


def check_output_dir(out_dir: str | Path, overwrite: bool, names: tuple[str, ...]) -> Path:
    """What :func:`make_output_dir` and an output check would refuse, without creating anything: so a
    command can check every input before it writes (or imports) anything."""
    out = Path(out_dir)
    if out.exists():
        if not out.is_dir():
            raise InputError(f"{out}: exists and is not a folder")
        if not os.access(out, os.W_OK):
            raise InputError(f"{out}: output folder is not writable")
        existing = [n for n in names if (out / n).exists()]
        if existing and not overwrite:
            raise InputError(f"{out / existing[0]}: already exists (pass --overwrite to replace it)")
        return out
    parent = out.absolute().parent
    while not parent.exists():
        parent = parent.parent
    if not parent.is_dir():
        raise InputError(f"{out}: cannot create the output folder ({parent} is a file)")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise InputError(f"{out}: cannot create the output folder ({parent} is not writable)")
    return out


def make_output_dir(out_dir: str | Path) -> Path:
    """Create ``out_dir`` (and parents) if needed; :class:`InputError` when it is a file or not writable."""
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise InputError(f"{out}: exists and is not a folder")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"{out}: cannot create the output folder ({exc.strerror})") from None
    if not os.access(out, os.W_OK):
        raise InputError(f"{out}: output folder is not writable")
    return out
