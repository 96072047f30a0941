"""Artifact keys: sha256 of canonical JSON, chained like a Merkle DAG (DESIGN §5).

A stage's key hashes its name, its version, its parameters, the keys of its inputs, the package
version and the CPU kernels' tag, so changing one parameter changes that stage's key and every key
downstream of it, and nothing upstream. Root inputs (video files) are keyed by a streamed digest of their bytes.
"""

from __future__ import annotations

import dataclasses
import enum
import hashlib
import json
import math
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

import multithumbs
from multithumbs.cpu_kernels import kernel_tag

KEY_LENGTH = 64
"""Hex characters of a key (sha256)."""


def _canonical(value: Any) -> Any:
    """Plain JSON values with a single spelling: sorted dicts, lists, finite floats, tagged non-finites."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {"__dataclass__": type(value).__name__,
                **{f.name: _canonical(getattr(value, f.name)) for f in dataclasses.fields(value)}}
    if isinstance(value, Mapping):
        keys = [str(k) for k in value]
        if len(set(keys)) != len(keys):
            raise ValueError("parameters: two keys have the same string form")
        return {str(k): _canonical(v) for k, v in sorted(value.items(), key=lambda kv: str(kv[0]))}
    if isinstance(value, (list, tuple)):
        return [_canonical(v) for v in value]
    if isinstance(value, np.ndarray):
        return {"__ndarray__": str(value.dtype), "shape": list(value.shape), "data": _canonical(value.tolist())}
    if isinstance(value, np.generic):
        return _canonical(value.item())
    if isinstance(value, enum.Enum):
        return _canonical(value.value)
    if isinstance(value, Path):
        return str(value)
    if isinstance(value, bool) or value is None or isinstance(value, (int, str)):
        return value
    if isinstance(value, float):
        if math.isfinite(value):
            return float(repr(value)) if value != 0 else 0.0  # -0.0 and 0.0 hash alike
        return {"__float__": repr(value)}
    raise TypeError(f"parameters: cannot key a value of type {type(value).__name__}")


def canonical_json(value: Any) -> bytes:
    """The canonical JSON bytes of ``value`` (dataclasses, numpy values and paths included)."""
    return json.dumps(_canonical(value), sort_keys=True, separators=(",", ":"), ensure_ascii=True,
                      allow_nan=False).encode("ascii")


def artifact_key(stage: str, stage_version: str | int, params: Any, input_keys: Sequence[str] | Mapping[str, str] = (),
                 package_version: str = multithumbs.__version__) -> str:
    """Key of a stage's output: sha256 over {stage, version, parameters, input keys, package version, the CPU
    kernels in use}. The last is the same on every AVX2 machine (:mod:`multithumbs.cpu_kernels`); bytes made
    with other kernels round differently, so they get keys of their own."""
    record = {"stage": stage, "stage_version": str(stage_version), "params": params,
              "inputs": dict(input_keys) if isinstance(input_keys, Mapping) else list(input_keys),
              "package_version": package_version, "kernels": kernel_tag()}
    return hashlib.sha256(canonical_json(record)).hexdigest()


def file_digest(path: str | Path, chunk_size: int = 1 << 20) -> str:
    """sha256 of a file's bytes, read in chunks (videos are large)."""
    digest = hashlib.sha256()
    with open(path, "rb") as fh:
        while block := fh.read(chunk_size):
            digest.update(block)
    return digest.hexdigest()


def is_key(text: str) -> bool:
    """Whether ``text`` looks like an artifact key."""
    return len(text) == KEY_LENGTH and all(c in "0123456789abcdef" for c in text)
