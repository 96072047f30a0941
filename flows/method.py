"""Submitting the method's stages for many reconstructions at once (used by every flow).

Stages run in waves (all alignments, then all propagations, re-IDs, post-processings), each wave's tasks
in parallel on the flow's task runner. Submissions with the same artifact key (variants sharing a stage,
the same video twice) are submitted once, so a benchmark computes each shared stage a single time.
"""

from __future__ import annotations

from typing import Sequence

from storage.store import ArtifactRef
from tasks.artifacts import stage_key
from tasks.method import align_cut, post_process_world, propagate_shots, reidentify_people

Inputs = dict[str, ArtifactRef]


def _wave(task, store_url: str, calls: Sequence[tuple[Inputs, dict]]) -> list[ArtifactRef]:
    """Run ``task`` on every ``(inputs, params)`` (identical keys once); refs in the order of ``calls``."""
    keys = [stage_key(task.name, params, inputs) for inputs, params in calls]
    futures = {}
    for key, (inputs, params) in zip(keys, calls):
        if key not in futures:
            futures[key] = task.submit(store_url, inputs, params)
    refs = {key: future.result() for key, future in futures.items()}
    return [refs[key] for key in keys]


def num_shots(inputs: Inputs) -> int:
    return sum(1 for name in inputs if name.startswith("tracks_"))


def run_method(store_url: str, jobs: Sequence[tuple[Inputs, dict[str, dict]]]) -> list[ArtifactRef]:
    """The method on every job ``(inputs, params)`` -> its ``WorldResult`` ref.

    ``inputs`` holds ``shots``, ``tracks_k``, ``trajectory_k`` for every shot and ``space_c`` for every cut;
    ``params`` is :func:`tasks.method.method_params` of the job's variant.
    """
    align_calls, owners = [], []
    for j, (inputs, params) in enumerate(jobs):
        if params["propagate"]["independent"]:
            continue  # the single-shot baseline has no shared space
        for c in range(num_shots(inputs) - 1):
            align_calls.append(({"tracks_before": inputs[f"tracks_{c}"], "tracks_after": inputs[f"tracks_{c + 1}"],
                                 "space": inputs[f"space_{c}"]}, params["align"]))
            owners.append((j, c))
    aligned: list[dict[str, ArtifactRef]] = [{} for _ in jobs]
    for (j, c), ref in zip(owners, _wave(align_cut, store_url, align_calls)):
        aligned[j][f"aligned_{c}"] = ref

    per_shot = [{k: v for k, v in inputs.items() if k == "shots" or k.startswith(("tracks_", "trajectory_"))}
                for inputs, _ in jobs]
    placements = _wave(propagate_shots, store_url,
                       [({**per_shot[j], **aligned[j]}, params["propagate"]) for j, (_, params) in enumerate(jobs)])
    tracks = [{k: v for k, v in shot_inputs.items() if not k.startswith("trajectory_")} for shot_inputs in per_shot]
    identities = _wave(reidentify_people, store_url,
                       [({**tracks[j], "placement": placements[j]}, params["reid"]) for j, (_, params) in enumerate(jobs)])
    return _wave(post_process_world, store_url,
                 [({**tracks[j], **aligned[j], "placement": placements[j], "identities": identities[j]}, params["post"])
                  for j, (_, params) in enumerate(jobs)])
