"""A content-addressed store of immutable zarr v3 groups, one per artifact (DESIGN §5).

Layout under the store's root (a local folder or any fsspec URL, e.g. ``s3://bucket/prefix``)::

    artifacts/<key>/      one zarr v3 group: arrays + attributes (provenance, checksums)
    index/<key>.json      commit record, written last: readers trust only indexed artifacts
    tmp/<key>.<nonce>/    work in progress (local stores), renamed into artifacts/ on commit

Commit: on a local store the finished group is renamed into place (atomic); on object stores the
group is written under its key and the index record is written last. Two writers of one key write the
same bytes (keys are content addresses) and the first commit wins. Every array's sha256 is recorded
at write time; reading verifies it, so a truncated or altered chunk is detected (:class:`CorruptArtifact`)
and the caller recomputes.
"""

from __future__ import annotations

import hashlib
import json
import os
import time
import uuid
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterable

import fsspec
import numpy as np

from storage.keys import is_key

# zarr (~0.3 s to import) is imported where arrays are read or written: whether an artifact exists is a
# question for fsspec alone, and a re-run served from the store asks nothing else.


class CorruptArtifact(RuntimeError):
    """An artifact's arrays do not match the checksums recorded when it was written."""


@dataclass(frozen=True)
class ArtifactRef:
    """A small, picklable handle to a committed artifact (what tasks pass instead of arrays).

    Attributes:
        key: the content address.
        stage: the stage that produced it.
        store: URL of the store's root.
    """

    key: str
    stage: str
    store: str


def _checksum(array: np.ndarray) -> str:
    return hashlib.sha256(np.ascontiguousarray(array).tobytes()).hexdigest()


class ArtifactStore:
    """Content-addressed zarr store rooted at a local path or fsspec URL."""

    def __init__(self, url: str | Path, **storage_options: Any):
        """Open (creating folders as needed) the store at ``url``; ``storage_options`` go to fsspec
        (e.g. ``client_kwargs={"endpoint_url": ...}`` for an S3-compatible server)."""
        self.url = str(url)
        self.storage_options = storage_options
        self.fs, self.root = fsspec.core.url_to_fs(self.url, **storage_options)
        self.local = isinstance(self.fs, fsspec.implementations.local.LocalFileSystem)
        if self.local:
            self.root = os.path.abspath(self.root)
        for sub in ("artifacts", "index", "tmp"):
            self.fs.makedirs(f"{self.root}/{sub}", exist_ok=True)

    # paths -------------------------------------------------------------------------------------
    def _group_path(self, key: str) -> str:
        return f"{self.root}/artifacts/{key}"

    def _index_path(self, key: str) -> str:
        return f"{self.root}/index/{key}.json"

    def _zarr_store(self, path: str, read_only: bool):
        import zarr

        if self.local:
            return zarr.storage.LocalStore(path, read_only=read_only)
        # zarr drives its own event loop: give it its own filesystem instance built from the URL.
        protocol = self.fs.protocol if isinstance(self.fs.protocol, str) else self.fs.protocol[0]
        return zarr.storage.FsspecStore.from_url(f"{protocol}://{path}", storage_options=self.storage_options,
                                                 read_only=read_only)

    # queries -----------------------------------------------------------------------------------
    def _fresh(self) -> None:
        """Object-store listings are cached by fsspec; other processes write too."""
        if not self.local:
            self.fs.invalidate_cache()

    def exists(self, key: str) -> bool:
        """Whether ``key`` is committed (its index record exists)."""
        self._fresh()
        return self.fs.exists(self._index_path(key))

    def keys(self) -> list[str]:
        """Committed keys."""
        self._fresh()
        try:
            names = [Path(p).name for p in self.fs.ls(f"{self.root}/index", detail=False)]
        except FileNotFoundError:  # object stores have no empty folders
            return []
        return sorted(n[:-5] for n in names if n.endswith(".json") and is_key(n[:-5]))

    def record(self, key: str) -> dict[str, Any]:
        """The commit record of ``key`` (stage, provenance, array checksums)."""
        with self.fs.open(self._index_path(key), "r") as fh:
            return json.load(fh)

    # write -------------------------------------------------------------------------------------
    def write(self, key: str, stage: str, arrays: dict[str, np.ndarray], attributes: dict[str, Any]) -> ArtifactRef:
        """Write and commit an artifact (a no-op if ``key`` is already committed).

        Args:
            key: content address (:func:`storage.keys.artifact_key`).
            stage: producing stage, recorded.
            arrays: name -> array; names may contain ``/`` for nesting.
            attributes: JSON-serialisable provenance and small values.
        """
        if not is_key(key):
            raise ValueError(f"artifact key {key!r}: not a sha256 hex digest")
        ref = ArtifactRef(key, stage, self.url)
        if self.exists(key):
            return ref
        checksums = {name: _checksum(np.asarray(a)) for name, a in arrays.items()}
        record = {"key": key, "stage": stage, "created": time.time(), "checksums": checksums,
                  "attributes": attributes}
        target = self._group_path(key)
        work = f"{self.root}/tmp/{key}.{uuid.uuid4().hex}" if self.local else target
        if not self.local and self.fs.exists(target):
            self.fs.rm(target, recursive=True)  # leftovers of a writer that died before its commit record
        import zarr
        from zarr.codecs import BloscCodec

        try:
            group = zarr.create_group(store=self._zarr_store(work, read_only=False),
                                      attributes={"multithumbs": record}, zarr_format=3)
            for name, value in arrays.items():
                value = np.asarray(value)
                if value.dtype.kind not in "biufc":
                    raise TypeError(f"artifact {stage}: array {name!r} has unsupported dtype {value.dtype}")
                group.create_array(name, data=value, chunks=_chunks(value.shape),
                                   compressors=BloscCodec(cname="zstd", clevel=5, shuffle="shuffle"))
            if self.local:
                try:
                    os.rename(work, target)
                except OSError:
                    if not os.path.isdir(target):
                        raise
                    self.fs.rm(work, recursive=True)  # another writer committed the same content first
        except BaseException:
            if self.local and self.fs.exists(work):
                self.fs.rm(work, recursive=True)
            raise
        self._write_index(key, record)
        return ref

    def _write_index(self, key: str, record: dict[str, Any]) -> None:
        data = json.dumps(record, sort_keys=True).encode()
        if self.local:
            tmp = f"{self.root}/tmp/{key}.{uuid.uuid4().hex}.json"
            with open(tmp, "wb") as fh:
                fh.write(data)
            os.replace(tmp, self._index_path(key))
        else:
            with self.fs.open(self._index_path(key), "wb") as fh:
                fh.write(data)

    # read --------------------------------------------------------------------------------------
    def read(self, key: str, verify: bool = True) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        """Arrays and attributes of a committed artifact; checksums verified unless ``verify=False``.

        Raises:
            KeyError: not committed.
            CorruptArtifact: an array is unreadable or differs from its recorded checksum.
        """
        if not self.exists(key):
            raise KeyError(f"artifact {key} is not in the store {self.url}")
        import zarr

        record = self.record(key)
        try:
            group = zarr.open_group(store=self._zarr_store(self._group_path(key), read_only=True), mode="r")
            arrays = {name: np.asarray(group[name][...]) for name in record["checksums"]}
        except Exception as exc:  # a missing or truncated chunk surfaces as a codec or key error
            raise CorruptArtifact(f"artifact {key}: unreadable ({exc.__class__.__name__}: {exc})") from exc
        if verify:
            for name, digest in record["checksums"].items():
                if _checksum(arrays[name]) != digest:
                    raise CorruptArtifact(f"artifact {key}: array {name!r} does not match its checksum")
        return arrays, record["attributes"]

    # maintenance -------------------------------------------------------------------------------
    def delete(self, key: str) -> None:
        """Remove an artifact: its commit record first, so readers stop trusting it at once."""
        if self.fs.exists(self._index_path(key)):
            self.fs.rm(self._index_path(key))
        if self.fs.exists(self._group_path(key)):
            self.fs.rm(self._group_path(key), recursive=True)

    def gc(self, keep: Iterable[str], dry_run: bool = False, stale_seconds: float = 3600.0) -> list[str]:
        """Delete committed artifacts not in ``keep`` and uncommitted leftovers; returns what went.

        Leftovers are groups without a commit record and, in ``tmp/``, work of writers that died (killed
        mid-write) older than ``stale_seconds`` — younger ones may belong to a writer still running.
        """
        keep = set(keep)
        removed = [k for k in self.keys() if k not in keep]
        if not dry_run:
            for key in removed:
                self.delete(key)
            committed = set(self.keys())
            try:
                leftovers = self.fs.ls(f"{self.root}/artifacts", detail=False)
            except FileNotFoundError:
                leftovers = []
            for path in leftovers:
                if Path(path).name not in committed:
                    self.fs.rm(path, recursive=True)
                    removed.append(Path(path).name)
            if self.local:
                now = time.time()
                for entry in os.scandir(f"{self.root}/tmp"):
                    if now - entry.stat(follow_symlinks=False).st_mtime >= stale_seconds:
                        self.fs.rm(entry.path, recursive=True)
                        removed.append(f"tmp/{entry.name}")
        return removed


def _chunks(shape: tuple[int, ...], target_bytes: int = 4 << 20, itemsize: int = 8) -> tuple[int, ...]:
    """Chunks of about ``target_bytes``: whole trailing dimensions, split along the leading ones."""
    if not shape:
        return ()
    chunks = list(shape)
    size = int(np.prod([max(1, s) for s in shape])) * itemsize
    for axis in range(len(shape)):
        if size <= target_bytes:
            break
        per_step = size // max(1, shape[axis])
        chunks[axis] = max(1, target_bytes // max(1, per_step))
        size = chunks[axis] * per_step
    return tuple(max(1, c) for c in chunks)
