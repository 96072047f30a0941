"""Submitting the method's stages for many reconstructions at once (used by every flow).

Stages run in waves (all alignments, then all propagations, re-IDs, post-processings), each wave's tasks
in parallel on the flow's task runner. Submissions with the same artifact key (variants sharing a stage,
the same video twice) are submitted once, so a benchmark computes each shared stage a single time.
"""

from __future__ import annotations

import time
from typing import Sequence

from storage.store import ArtifactRef
from tasks.artifacts import stage_key
from tasks.method import align_cut, post_process_world, propagate_shots, reidentify_people

Inputs = dict[str, ArtifactRef]


def _wave(task, store_url: str, calls: Sequence[tuple[Inputs, dict]], smpl_model: str | None = None
          ) -> list[ArtifactRef]:
    """Run ``task`` on every ``(inputs, params)`` (identical keys once); refs in the order of ``calls``."""
    keys = [stage_key(task.name, params, inputs) for inputs, params in calls]
    futures = {}
    for key, (inputs, params) in zip(keys, calls):
        if key not in futures:
            futures[key] = task.submit(store_url, inputs, params, smpl_model)
    refs = {key: future.result() for key, future in futures.items()}
    return [refs[key] for key in keys]


def num_shots(inputs: Inputs) -> int:
    return sum(1 for name in inputs if name.startswith("tracks_"))


def space_refs(inputs: Inputs) -> list[ArtifactRef]:
    """The shared-space refs of every cut, in cut order."""
    return [inputs[f"space_{c}"] for c in range(num_shots(inputs) - 1)]


def run_method(store_url: str, jobs: Sequence[tuple[Inputs, dict[str, dict]]],
               timings: dict[str, float] | None = None, smpl_model: str | None = None) -> list[dict[str, ArtifactRef]]:
    """The method on every job ``(inputs, params)``.

    ``inputs`` holds ``shots``, ``tracks_k``, ``trajectory_k`` for every shot and ``space_c`` for every cut;
    ``params`` is :func:`tasks.method.method_params` of the job's variant. Returns per job the refs of its
    ``aligned_c``, ``placement``, ``identities`` and ``result`` (the ``WorldResult``); ``timings`` (if given)
    receives the wall seconds of each stage's wave. ``smpl_model`` is the body file the stages pose (None:
    the procedural body); its identity must be in ``params`` (:func:`tasks.body.resolve_body`).
    """
    clock = time.perf_counter()

    def lap(stage: str) -> None:
        nonlocal clock
        if timings is not None:
            timings[stage] = timings.get(stage, 0.0) + time.perf_counter() - clock
        clock = time.perf_counter()

    align_calls, owners = [], []
    for j, (inputs, params) in enumerate(jobs):
        if params["propagate"]["independent"]:
            continue  # the single-shot baseline has no shared space
        for c in range(num_shots(inputs) - 1):
            align_calls.append(({"tracks_before": inputs[f"tracks_{c}"], "tracks_after": inputs[f"tracks_{c + 1}"],
                                 "space": inputs[f"space_{c}"]}, params["align"]))
            owners.append((j, c))
    aligned: list[dict[str, ArtifactRef]] = [{} for _ in jobs]
    for (j, c), ref in zip(owners, _wave(align_cut, store_url, align_calls, smpl_model)):
        aligned[j][f"aligned_{c}"] = ref
    lap("alignment")

    per_shot = [{k: v for k, v in inputs.items() if k == "shots" or k.startswith(("tracks_", "trajectory_"))}
                for inputs, _ in jobs]
    placements = _wave(propagate_shots, store_url,
                       [({**per_shot[j], **aligned[j]}, params["propagate"]) for j, (_, params) in enumerate(jobs)],
                       smpl_model)
    lap("propagation")
    tracks = [{k: v for k, v in shot_inputs.items() if not k.startswith("trajectory_")} for shot_inputs in per_shot]
    identities = _wave(reidentify_people, store_url,
                       [({**tracks[j], "placement": placements[j]}, params["reid"]) for j, (_, params) in enumerate(jobs)])
    lap("re-identification")
    results = _wave(post_process_world, store_url,
                    [({**tracks[j], **aligned[j], "placement": placements[j], "identities": identities[j]}, params["post"])
                     for j, (_, params) in enumerate(jobs)], smpl_model)
    lap("post-processing")
    return [{**aligned[j], "placement": placements[j], "identities": identities[j], "result": results[j]}
            for j in range(len(jobs))]
