"""Tasks of the method's stages (paper §3.2–3.5): alignment per cut, propagation, re-identification,
post-processing. Each key hashes only the parameters its stage reads, so changing a re-ID parameter gives
re-ID and post-processing new keys and leaves alignment and propagation served from the store.
"""

from __future__ import annotations

import dataclasses
from typing import Any

from multithumbs.overrides import METHOD_SECTIONS, method_config  # noqa: F401  (re-exported)
from storage.store import ArtifactRef
from tasks.artifacts import cached_stage, load, stage_task
from tasks.body import without_body


def method_params(variant: str = "full", overrides: dict[str, Any] | None = None,
                  body: dict[str, str] | None = None) -> dict[str, dict]:
    """JSON parameters of each method stage (exactly what its key hashes).

    ``body`` is the body model's identity (:func:`tasks.body.resolve_body`), added to the stages that pose
    bodies (alignment, propagation, post-processing); re-identification does not.
    """
    config = method_config(variant, overrides)
    body = body or {}
    return {
        "align": {"align": dataclasses.asdict(config.align), "skip": config.skip_align, **body},
        "propagate": {"independent": config.independent_shots,
                      "propagate_orientation": config.propagate_orientation, **body},
        "reid": {"reid": dataclasses.asdict(config.reid), "appearance_window": config.appearance_window},
        "post": {"post": dataclasses.asdict(config.post), "skip_post": config.skip_post,
                 "variant": config.variant, **body},
    }


def _section(cls, values: dict):
    return cls(**{k: tuple(v) if isinstance(v, list) else v for k, v in values.items()})


def _tracks(inputs: dict[str, ArtifactRef], n_shots: int) -> list:
    from multithumbs.pipeline import sanitize_tracks

    return [sanitize_tracks(load(inputs[f"tracks_{k}"])) for k in range(n_shots)]


def _aligned(inputs: dict[str, ArtifactRef], n_shots: int) -> list:
    return [load(inputs[f"aligned_{c}"]) for c in range(n_shots - 1) if f"aligned_{c}" in inputs]


@stage_task("align")
def align_cut(store_url: str, inputs: dict[str, ArtifactRef], params: dict,
              smpl_model: str | None = None) -> ArtifactRef:
    """Scale and three-stage alignment at one cut (inputs: ``tracks_before``, ``tracks_after``, ``space``)."""
    def compute():
        from multithumbs.body.model import load_body_model
        from multithumbs.method.align import AlignConfig, align_boundary
        from multithumbs.pipeline import boundary_people, sanitize_tracks

        space = load(inputs["space"])
        people = boundary_people(sanitize_tracks(load(inputs["tracks_before"])),
                                 sanitize_tracks(load(inputs["tracks_after"])), load_body_model(smpl_model),
                                 K=space.K)
        return align_boundary(people, space, _section(AlignConfig, params["align"]),
                              skip=params["skip"])
    return cached_stage("align", compute, store_url, params, inputs)


@stage_task("propagate")
def propagate_shots(store_url: str, inputs: dict[str, ArtifactRef], params: dict,
                    smpl_model: str | None = None) -> ArtifactRef:
    """Every shot's cameras and people in the world frame (inputs: ``shots``, ``tracks_k``, ``trajectory_k``,
    ``aligned_c``)."""
    def compute():
        from multithumbs.body.model import load_body_model
        from multithumbs.pipeline import propagate

        shots = load(inputs["shots"])
        trajectories = [load(inputs[f"trajectory_{k}"]) for k in range(shots.num_shots)]
        return propagate(shots, _tracks(inputs, shots.num_shots), trajectories, _aligned(inputs, shots.num_shots),
                         load_body_model(smpl_model), **without_body(params))
    return cached_stage("propagate", compute, store_url, params, inputs)


@stage_task("reid")
def reidentify_people(store_url: str, inputs: dict[str, ArtifactRef], params: dict,
                      smpl_model: str | None = None) -> ArtifactRef:
    """Global identities across cuts (inputs: ``shots``, ``tracks_k``, ``placement``). ``smpl_model`` is
    unused (re-ID poses no bodies): it keeps every method stage's call alike."""
    def compute():
        from multithumbs.method.reid import ReidConfig
        from multithumbs.method.identities import reidentify

        shots = load(inputs["shots"])
        return reidentify(_tracks(inputs, shots.num_shots), load(inputs["placement"]),
                          _section(ReidConfig, params["reid"]), params["appearance_window"], shots.fps)
    return cached_stage("reid", compute, store_url, params, inputs)


@stage_task("post")
def post_process_world(store_url: str, inputs: dict[str, ArtifactRef], params: dict,
                       smpl_model: str | None = None) -> ArtifactRef:
    """Assembly, post-processing and the :class:`WorldResult` (inputs: ``shots``, ``tracks_k``, ``aligned_c``,
    ``placement``, ``identities``)."""
    def compute():
        from multithumbs.body.model import load_body_model
        from multithumbs.method.post import PostConfig
        from multithumbs.pipeline import MethodConfig, finish_world

        shots = load(inputs["shots"])
        config = MethodConfig(post=_section(PostConfig, params["post"]), skip_post=params["skip_post"],
                              variant=params["variant"])
        return finish_world(shots, _tracks(inputs, shots.num_shots), _aligned(inputs, shots.num_shots),
                            load(inputs["placement"]), load(inputs["identities"]), load_body_model(smpl_model),
                            config)
    return cached_stage("post", compute, store_url, params, inputs)
