"""Clip specs of the multi-shot benchmark (:mod:`multithumbs.datasets.benchmark`): which captured frames make a clip.

A :class:`ClipSpec` (JSON or TOML) names the dataset, sequence, cameras (one per shot), cuts, frames and
people; anyone holding the data rebuilds the same clip:

    name = "egohumans_tagging_001_ab"
    dataset = "egohumans"           # egohumans | harmony4d | egobody
    sequence = "01_tagging/001_tagging"
    cameras = ["cam01", "cam02"]    # camera of each shot
    cuts = [60]                     # clip frames where a new shot starts
    start = 0                       # first frame: 0-based index into the sequence's usable frames
    num_frames = 120
    stride = 1                      # take every stride-th frame
    people = ["aria01", "aria02"]   # optional (default: everyone with ground truth in the clip)
    image_size = [540, 960]         # optional [H, W] (default: the first camera's size)
    fps = 20.0                      # optional (default: the dataset's rate / stride)
    level = true                    # optional: re-express the world +z up, floor at z = 0
"""

from __future__ import annotations

import json
import re
import tomllib
from dataclasses import asdict, dataclass, fields
from pathlib import Path
from typing import Any, Iterable

import numpy as np

from multithumbs.conventions import NUM_JOINTS
from multithumbs.errors import InputError

CAPTURE_DATASETS = ("egohumans", "harmony4d", "egobody")
_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]*$")


@dataclass(frozen=True)
class ClipSpec:
    """A deterministic multi-shot clip of one multi-view sequence.

    Attributes:
        name: the clip's folder name (letters, digits, ``.``, ``_``, ``-``).
        dataset: ``"egohumans"``, ``"harmony4d"`` or ``"egobody"``.
        sequence: the sequence under the data root (see the loaders).
        cameras: the camera of each shot, in order (a camera may return in a later shot).
        cuts: clip frames where a new shot starts, strictly increasing inside ``(0, num_frames)``.
        num_frames: frames in the clip.
        start: the clip's first frame as a 0-based index into the sequence's usable frames.
        stride: take every ``stride``-th usable frame.
        people: the people to include, in this order (their ids are 0, 1, ...); None: everyone with
            ground truth somewhere in the clip, sorted by name.
        image_size: ``(H, W)`` of the video; None: the first camera's size. Other cameras are resized
            to it (and their ``K`` scaled).
        fps: frames per second of the clip; None: the dataset's rate divided by ``stride``.
        level: re-express the world with ``+z`` up and the floor at ``z = 0`` (the project's ground-truth
            convention); False keeps the dataset's metric world.
        min_visible_joints: joints that must project inside the image for a person to count as visible.
    """

    name: str
    dataset: str
    sequence: str
    cameras: tuple[str, ...]
    cuts: tuple[int, ...]
    num_frames: int
    start: int = 0
    stride: int = 1
    people: tuple[str, ...] | None = None
    image_size: tuple[int, int] | None = None
    fps: float | None = None
    level: bool = True
    min_visible_joints: int = 5

    def __post_init__(self) -> None:
        where = f"spec {self.name!r}"
        if not isinstance(self.name, str) or not _NAME.match(self.name):
            raise InputError(f"spec name {self.name!r}: use letters, digits, '.', '_' and '-' (it names a folder)")
        if self.dataset not in CAPTURE_DATASETS:
            raise InputError(f"{where}: dataset must be one of {', '.join(CAPTURE_DATASETS)}, got {self.dataset!r}")
        object.__setattr__(self, "cameras", tuple(str(c) for c in self.cameras))
        object.__setattr__(self, "cuts", tuple(_int(c, f"{where} cuts") for c in self.cuts))
        for key in ("num_frames", "start", "stride", "min_visible_joints"):
            object.__setattr__(self, key, _int(getattr(self, key), f"{where} {key}"))
        if self.num_frames < 1 or self.start < 0 or self.stride < 1 or not 0 <= self.min_visible_joints <= NUM_JOINTS:
            raise InputError(f"{where}: need num_frames >= 1, start >= 0, stride >= 1, "
                             f"0 <= min_visible_joints <= {NUM_JOINTS}")
        if len(self.cameras) != len(self.cuts) + 1:
            raise InputError(f"{where}: {len(self.cameras)} cameras for {len(self.cuts) + 1} shots "
                             f"(one camera per shot: len(cameras) = len(cuts) + 1)")
        edges = (0, *self.cuts, self.num_frames)
        if any(b <= a for a, b in zip(edges[:-1], edges[1:])):
            raise InputError(f"{where}: cuts must increase strictly inside (0, {self.num_frames}), got {list(self.cuts)}")
        if self.people is not None:
            people = tuple(str(p) for p in self.people)
            if len(set(people)) != len(people):
                raise InputError(f"{where}: people lists a person twice")
            object.__setattr__(self, "people", people)
        if self.image_size is not None:
            size = tuple(_int(s, f"{where} image_size") for s in self.image_size)
            if len(size) != 2 or min(size) < 8:
                raise InputError(f"{where}: image_size is [H, W] with both at least 8, got {list(self.image_size)}")
            object.__setattr__(self, "image_size", size)
        if self.fps is not None and not (isinstance(self.fps, (int, float)) and self.fps > 0):
            raise InputError(f"{where}: fps must be a positive number, got {self.fps!r}")
        if not isinstance(self.level, bool):
            raise InputError(f"{where}: level must be true or false, got {self.level!r}")

    @property
    def indices(self) -> np.ndarray:
        """``(T,)`` the 0-based sequence frames the clip takes."""
        return self.start + self.stride * np.arange(self.num_frames, dtype=np.int64)

    def to_json(self) -> dict[str, Any]:
        """Canonical JSON form (lists for tuples; every field present)."""
        out = asdict(self)
        for key in ("cameras", "cuts", "people", "image_size"):
            if out[key] is not None:
                out[key] = list(out[key])
        return out


def _int(value: Any, where: str) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) and not (
            isinstance(value, float) and value.is_integer()):
        raise InputError(f"{where}: expected an integer, got {value!r}")
    return int(value)


def spec_from_dict(data: dict[str, Any], source: str = "spec") -> ClipSpec:
    """A :class:`ClipSpec` from parsed JSON/TOML, naming unknown or missing fields."""
    if not isinstance(data, dict):
        raise InputError(f"{source}: expected a table of fields, got {type(data).__name__}")
    known = {f.name for f in fields(ClipSpec)}
    unknown = sorted(set(data) - known)
    if unknown:
        raise InputError(f"{source}: unknown field {unknown[0]!r} (fields: {', '.join(sorted(known))})")
    for required in ("name", "dataset", "sequence", "cameras", "cuts", "num_frames"):
        if required not in data:
            raise InputError(f"{source}: missing field {required!r}")
    for key in ("cameras", "cuts", "people", "image_size"):
        if key in data and data[key] is not None and not isinstance(data[key], (list, tuple)):
            raise InputError(f"{source}: {key} must be a list, got {data[key]!r}")
    try:
        return ClipSpec(**data)
    except InputError as error:
        raise InputError(f"{source}: {error}") from None


def load_spec(path: str | Path) -> ClipSpec:
    """Read a spec file (``.json`` or ``.toml``)."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: no such spec file")
    try:
        if path.suffix.lower() == ".toml":
            data = tomllib.loads(path.read_text())
        elif path.suffix.lower() == ".json":
            data = json.loads(path.read_text())
        else:
            raise InputError(f"{path}: a spec is a .json or .toml file")
    except (ValueError, tomllib.TOMLDecodeError) as error:
        raise InputError(f"{path}: not valid {path.suffix[1:].upper()} ({str(error).splitlines()[0]})") from None
    return spec_from_dict(data, str(path))


def load_specs(paths: Iterable[str | Path]) -> list[ClipSpec]:
    """Specs from files; a ``.json`` file may also hold a list of specs (a whole benchmark)."""
    specs: list[ClipSpec] = []
    for path in paths:
        path = Path(path)
        if path.suffix.lower() == ".json" and path.is_file():
            try:
                data = json.loads(path.read_text())
            except ValueError as error:
                raise InputError(f"{path}: not valid JSON ({error})") from None
            if isinstance(data, list):
                specs.extend(spec_from_dict(item, f"{path}[{k}]") for k, item in enumerate(data))
                continue
        specs.append(load_spec(path))
    names = [s.name for s in specs]
    duplicate = next((n for n in names if names.count(n) > 1), None)
    if duplicate:
        raise InputError(f"specs: two specs are named {duplicate!r} (names are output folders)")
    return specs


__all__ = ["ClipSpec", "load_spec", "load_specs", "spec_from_dict"]
