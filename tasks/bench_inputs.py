"""The pixel inputs of ``multithumbs bench --from-pixels`` kept in an artifact store, so a second run is cheap.

The bench computes a rendered scene's inputs from its frames (:func:`multithumbs.bench.pixel_inputs`:
scenedetect, BlazePose, pycolmap), which takes minutes per scene. :class:`StoreInputCache` keeps what
they gave, per scene: one artifact per contract (the shots, each shot's tracks, each trajectory, each
shared space) and a manifest written last, so a run killed half-way leaves no entry a later run would
read. The key hashes the scene's settings, the stages taken from the pixels, whether the focal length
was withheld, the body model, the versions of the stages that produce these inputs in the flows
(:data:`tasks.artifacts.STAGE_VERSIONS`) and the package's version: a change to any of them computes
the inputs again.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from storage.codecs import decode, encode
from storage.keys import artifact_key
from storage.store import CorruptArtifact
from tasks.artifacts import STAGE_VERSIONS, open_store
from tasks.body import resolve_body

STAGE = "bench_pixel_inputs"
VERSION = "2-" + "-".join(str(STAGE_VERSIONS[s]) for s in ("shots", "perception", "trajectory", "space", "focal"))
"""This cache's own version, then those of the flow stages that make the same inputs. Version 2: inputs kept
by ``bench --workers 1`` on a machine with several cores held bodies fitted with a body model whose joint
regression had rounded at two threads (``multithumbs/body/model.py``); the flows' and the other benches'
rounded at one."""


@dataclass(frozen=True)
class StoreInputCache:
    """``load`` / ``save`` of a scene's pixel inputs in the store at ``url`` (module docstring); picklable,
    so the bench's worker processes share it."""

    url: str

    def _keys(self, params: dict, count: int | None = None) -> tuple[str, list[str]]:
        _, body = resolve_body(None)
        params = {**params, **body}
        manifest = artifact_key(STAGE, VERSION, params)
        return manifest, [artifact_key(STAGE, VERSION, {**params, "part": i}) for i in range(count or 0)]

    def load(self, params: dict) -> tuple | None:
        """``(shots, tracks, trajectories, spaces, backends, seconds)`` as saved, or None when absent (or
        any part of it unreadable)."""
        store = open_store(self.url)
        manifest, _ = self._keys(params)
        if not store.exists(manifest):
            return None
        try:
            _, attributes = store.read(manifest)
            counts = attributes["counts"]
            _, part_keys = self._keys(params, sum(counts))
            parts = [decode(*store.read(key)) for key in part_keys]
        except (CorruptArtifact, KeyError):
            return None
        shots, rest = parts[0], parts[1:]
        tracks, rest = rest[:counts[1]], rest[counts[1]:]
        trajectories, spaces = rest[:counts[2]], rest[counts[2]:]
        seconds = {k: float("nan") if v is None else v for k, v in attributes["seconds"].items()}
        return shots, tracks, trajectories, spaces, dict(attributes["backends"]), seconds

    def save(self, params: dict, value: tuple) -> None:
        """Keep ``value`` (as :meth:`load` returns it) under ``params``; the manifest goes last."""
        shots, tracks, trajectories, spaces, backends, seconds = value
        parts: list[Any] = [shots, *tracks, *trajectories, *spaces]
        store = open_store(self.url)
        manifest, part_keys = self._keys(params, len(parts))
        for key, part in zip(part_keys, parts):
            arrays, attributes = encode(part)
            attributes["provenance"] = {"params": params}
            store.write(key, STAGE, arrays, attributes)
        seconds = {k: None if v != v else float(v) for k, v in seconds.items()}  # JSON has no nan
        store.write(manifest, STAGE, {}, {"counts": [1, len(tracks), len(trajectories), len(spaces)],
                                          "backends": backends, "seconds": seconds, "provenance": {"params": params}})


__all__ = ["StoreInputCache", "VERSION"]
