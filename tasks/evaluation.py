"""The evaluation task: every metric of METRICS.md for a result against ground truth."""

from __future__ import annotations

import json
from typing import Any

from prefect import task
from prefect.cache_policies import NO_CACHE

from storage.store import ArtifactRef
from tasks.artifacts import load


@task(name="evaluate", cache_policy=NO_CACHE)
def evaluate_result(result: ArtifactRef, truth: ArtifactRef, smpl_model: str | None = None) -> dict[str, Any]:
    """Metrics of ``result`` against ``truth``, posed with ``smpl_model`` (None: the procedural body; small:
    returned as JSON, not stored)."""
    from multithumbs.body.model import load_body_model
    from multithumbs.metrics.evaluate import evaluate

    metrics = evaluate(load(result), load(truth), load_body_model(smpl_model))
    return json.loads(json.dumps(metrics, default=lambda o: o.tolist() if hasattr(o, "tolist") else str(o)))
