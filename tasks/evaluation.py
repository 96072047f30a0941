"""The evaluation task: every metric of METRICS.md for a result against ground truth, a stage like the others.

The metrics are stored as an artifact (their JSON text) in the result's store, keyed on the result's and
the truth's keys, the metric options, the body model's identity and the stage's version
(:data:`tasks.artifacts.STAGE_VERSIONS`): a re-run of the same result is served from the store without
importing the evaluation (or torch), and a new result, truth, option or body file scores again.
"""

from __future__ import annotations

import json
from typing import Any

import numpy as np
from prefect import task

from storage.store import ArtifactRef, CorruptArtifact
from tasks.artifacts import _retry_on_io, load, open_store, prefect_cache_key, stage_key

STAGE = "evaluate"


def evaluation_params(smpl_model: str | None = None, options: dict[str, Any] | None = None) -> dict[str, Any]:
    """What the evaluation's key hashes besides its inputs: the metric options (fields of
    :class:`~multithumbs.metrics.options.EvaluationOptions`, none for its defaults) and the body's identity
    (:func:`tasks.body.resolve_body` of ``smpl_model``: a user's file by its digest, nothing for the
    procedural body)."""
    from tasks.body import resolve_body

    _, body = resolve_body(smpl_model)
    return {"options": dict(options or {}), **body}


def evaluation_key(result: ArtifactRef, truth: ArtifactRef, params: dict[str, Any]) -> str:
    return stage_key(STAGE, params, {"result": result, "truth": truth})


def _cache_key(context, parameters: dict) -> str | None:
    """Prefect's cache key of the metrics in the result's store (:func:`tasks.artifacts.prefect_cache_key`)."""
    result, truth = parameters["result"], parameters["truth"]
    key = evaluation_key(result, truth, evaluation_params(parameters.get("smpl_model"), parameters.get("options")))
    return prefect_cache_key(context, key, result.store)


def _read(store, key: str) -> dict[str, Any]:
    arrays, _ = store.read(key)
    return json.loads(arrays["metrics_json"].tobytes().decode("utf-8"))


@task(name=STAGE, cache_key_fn=_cache_key, persist_result=True, retries=2, retry_delay_seconds=1,
      retry_condition_fn=_retry_on_io)
def evaluate_result(result: ArtifactRef, truth: ArtifactRef, smpl_model: str | None = None,
                    options: dict[str, Any] | None = None) -> dict[str, Any]:
    """Metrics of ``result`` against ``truth`` (JSON values, NaN where undefined), posed with ``smpl_model``
    (None: the procedural body), with the metric ``options`` (None: METRICS.md's defaults); computed once
    per key and stored in the result's store."""
    params = evaluation_params(smpl_model, options)
    store = open_store(result.store)
    key = evaluation_key(result, truth, params)
    if store.exists(key):
        try:
            return _read(store, key)
        except CorruptArtifact:
            store.delete(key)
    from multithumbs.body.model import load_body_model
    from multithumbs.metrics.evaluate import evaluate
    from tasks.artifacts import compute_fixed

    metrics = compute_fixed(lambda: evaluate(load(result), load(truth), load_body_model(smpl_model),
                                             **dict(options or {})))
    text = json.dumps(metrics, default=lambda o: o.tolist() if hasattr(o, "tolist") else str(o))
    store.write(key, STAGE, {"metrics_json": np.frombuffer(text.encode("utf-8"), np.uint8)},
                {"contract": "metrics", "provenance": {"params": params,
                                                        "inputs": {"result": result.key, "truth": truth.key}}})
    return json.loads(text)
