"""The store-backed stage wrapper every task uses (DESIGN §6).

Every task takes the store's URL, its inputs as :class:`~storage.store.ArtifactRef` s and its parameters
as plain JSON, computes its artifact key from them (:func:`storage.keys.artifact_key`), and returns the
ref without computing when the store already holds that key: the store is the source of truth.

Prefect's cache key (:func:`prefect_cache_key`) is that key with the store's URL: the ref it caches is then
exactly the one the store would give. A run whose store holds the key is served from Prefect's cache (no
function call, nothing read); a run that computes the artifact caches its ref under the key, so the next
run is served from the cache, not by the function checking the store. Only when the store lacks the key
while Prefect still holds a ref to it (the artifact was deleted) is the key withheld, so that the task runs
and recomputes rather than return a ref to nothing. A corrupt artifact is found when it is read: by the
task's own check when it runs (:func:`cached_stage`), or by the stage that loads it.
"""

from __future__ import annotations

import functools
import hashlib
from typing import Any, Callable

from prefect import task

from storage.codecs import decode, encode
from storage.keys import artifact_key
from storage.store import ArtifactRef, ArtifactStore, CorruptArtifact

STAGE_VERSIONS = {"simulate_inputs": 3, "ground_truth": 1, "shots": 2, "perception": 34, "trajectory": 2, "space": 2,
                  "focal": 3, "align": 6, "propagate": 4, "reid": 4, "post": 3, "evaluate": 1}
"""Bump a stage's version when its code changes its output: its key and every key after it change.
(Torch stages bumped together when every stage came to compute with one thread, :func:`compute_fixed`.)
``evaluate`` (:mod:`tasks.evaluation`) is the metrics: bump it when a metric's code or default changes.
Never reuse a number: caches keyed by it may hold other code's output (perception 24 was an A/B run of
stage 23 with ``TrackerConfig.reread=0``; 25 is the facing's turn cost 4; 26 drops a split's transit frames;
27 drops short tracks off the floor; 28 asks that their offset also stand out of the others' scatter about
it; 29 mirrors a twisted reading's hips and legs onto its shoulders' side; 30 labels frames whose hips are unseen
across the shoulders and reads the walk from bodies seen to one foot inside the image; 31 counts the walk's
motion along the view at half; 32 leaves tracks the frame's edge cuts unjudged by the floor check; 33 reads a
lost person's square again with the others greyed out, :mod:`multithumbs.perception.behind`; 34 bridges short
gaps inside a track, :mod:`multithumbs.perception.gap_fill`; the next is 35)."""


@functools.lru_cache(maxsize=8)
def open_store(url: str) -> ArtifactStore:
    return ArtifactStore(url)


def stage_key(stage: str, params: dict, inputs: dict[str, ArtifactRef]) -> str:
    """The artifact key of ``stage`` run with ``params`` on ``inputs`` (a Merkle DAG: inputs by their keys)."""
    return artifact_key(stage, STAGE_VERSIONS[stage], params, {k: r.key for k, r in sorted(inputs.items())})


def load(ref: ArtifactRef) -> Any:
    """The contract behind a ref."""
    return decode(*open_store(ref.store).read(ref.key))


def prefect_cache_key(context, key: str, store_url: str) -> str | None:
    """Prefect's cache key of the artifact ``key`` of the store at ``store_url`` (module docstring): the key
    and a digest of the URL, or None when the store lacks the artifact but Prefect has a ref to it cached."""
    cache_key = f"{key}-{hashlib.sha256(store_url.encode()).hexdigest()[:16]}"
    if open_store(store_url).exists(key):
        return cache_key
    results = getattr(context, "result_store", None)
    try:
        stale = results is None or results.exists(cache_key)
    except Exception:  # noqa: BLE001 - when in doubt, run the task and cache nothing
        stale = True
    return None if stale else cache_key


def _cache_key(stage: str) -> Callable:
    def key_fn(context, parameters: dict) -> str | None:
        key = stage_key(stage, parameters["params"], parameters["inputs"])
        return prefect_cache_key(context, key, parameters["store_url"])
    return key_fn


def cached_stage(stage: str, compute: Callable[[], Any], store_url: str, params: dict,
                 inputs: dict[str, ArtifactRef]) -> ArtifactRef:
    """Return the stage's artifact, computing and writing it only when the store lacks it (or it is corrupt)."""
    store = open_store(store_url)
    key = stage_key(stage, params, inputs)
    if store.exists(key):
        try:
            store.read(key)  # verify checksums: a corrupt artifact is recomputed, never trusted
            return ArtifactRef(key, stage, store_url)
        except CorruptArtifact:
            store.delete(key)
    arrays, attributes = encode(compute_fixed(compute))
    attributes["provenance"] = {"params": params, "inputs": {k: r.key for k, r in inputs.items()}}
    return store.write(key, stage, arrays, attributes)


def compute_fixed(compute: Callable[[], Any]) -> Any:
    """``compute()`` with the one thread count every stage computes with, set in this (the task runner's)
    thread: the results' rounding depends on it, and a key must always mean the same bytes
    (:mod:`multithumbs.determinism`)."""
    from multithumbs.determinism import fix_threads

    fix_threads()
    return compute()


def _retry_on_io(task, task_run, state) -> bool:
    try:
        state.result()
    except (OSError, TimeoutError):
        return True
    except Exception:
        return False
    return False


def stage_task(stage: str) -> Callable:
    """Decorate a stage function ``(store_url, inputs, params) -> ArtifactRef`` as a Prefect task with the
    store-backed cache key and retries on I/O errors."""
    return task(name=stage, cache_key_fn=_cache_key(stage), persist_result=True, retries=2,
                retry_delay_seconds=1, retry_condition_fn=_retry_on_io)
