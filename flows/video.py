"""The reconstruction flow of a real video: shots, perception, camera trajectories and shared spaces from
the video itself, then the method; cuts and shots processed in parallel (DESIGN §6)."""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path
from typing import Any

from prefect import flow
from prefect.task_runners import ThreadPoolTaskRunner

from flows.method import run_method, space_refs
from flows.reconstruct import publish_outputs
from tasks.evaluation import evaluate_result
from tasks.inputs import (detect_video_shots, estimate_video_focal, given_shots, import_ground_truth, perceive_people,
                          shared_space, spec_fingerprint, track_shot_camera)
from tasks.method import method_params


def intrinsics_matrix(intrinsics: list[float] | None, width: int, height: int) -> list[list[float]]:
    """``K`` from ``[fx, fy, cx, cy]``, or the documented guess for unknown cameras
    (:func:`multithumbs.scene.two_view.default_intrinsics`)."""
    from multithumbs.scene.two_view import default_intrinsics
    from multithumbs.video import check_intrinsics

    if intrinsics is None:
        return default_intrinsics(width, height).tolist()
    fx, fy, cx, cy = check_intrinsics(intrinsics)
    return [[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]]


@flow(name="reconstruct-video", task_runner=ThreadPoolTaskRunner(max_workers=2))
def reconstruct_video(video: str, out_dir: str, store_url: str, perception: str, trust_pickle: bool = False,
                      intrinsics: list[float] | None = None, variant: str = "full",
                      method: dict[str, Any] | None = None, truth: str | None = None,
                      shots: dict[str, Any] | None = None, tracking: dict[str, Any] | None = None,
                      two_view: dict[str, Any] | None = None, cuts: list[int] | None = None,
                      smpl_model: str | None = None, device: str = "auto") -> dict[str, Any]:
    """Reconstruct the people of an edited video in one world frame; write the result, pictures, exports and
    report to ``out_dir`` (and metrics when ``truth`` is given).

    Args:
        video: the video file. out_dir: output folder. store_url: artifact store (local path or fsspec URL).
        perception: perception spec (:func:`multithumbs.perception.load_perception`), e.g. ``phalp:RESULTS.pkl``.
        trust_pickle: allow loading pickled results (they run code when loaded).
        intrinsics: ``[fx, fy, cx, cy]`` of the video's camera; default: estimated from the pixels (the stage
            ``focal``: a moving camera, else people's heights, else a 60° horizontal field of view guess).
        variant, method: method variant and parameter overrides (:func:`tasks.method.method_config`).
        truth: optional ground-truth ``.npz`` to score against.
        shots, tracking, two_view: overrides of :class:`~multithumbs.scene.shots.ShotConfig`,
            :class:`~multithumbs.scene.tracking.TrackingConfig`, :class:`~multithumbs.scene.two_view_pose.TwoViewConfig`.
        cuts: the cut frames when they are known (a benchmark clip built from a spec); shot detection is
            then skipped and the shots' source is ``given``.
        smpl_model: the SMPL file (.npz or .pkl) every stage poses people with; default
            ``$MULTITHUMBS_SMPL_MODEL``, else the procedural body (:func:`tasks.body.resolve_body`).
    """
    import numpy as np

    from multithumbs.cpu_kernels import network_kernel_tag
    from multithumbs.scene.focal import FocalConfig, given_focal
    from multithumbs.scene.shots import ShotConfig
    from multithumbs.scene.tracking import TrackingConfig
    from multithumbs.scene.two_view_pose import TwoViewConfig
    from multithumbs.video import probe_video
    from storage.keys import file_digest
    from tasks.artifacts import load
    from tasks.body import resolve_body

    info = probe_video(video)
    body_path, body = resolve_body(smpl_model)
    K = intrinsics_matrix(intrinsics, info.width, info.height)
    digest = file_digest(video)
    Path(out_dir).mkdir(parents=True, exist_ok=True)
    timings: dict[str, float] = {}
    clock = time.perf_counter()

    def lap(stage: str) -> None:
        nonlocal clock
        timings[stage] = time.perf_counter() - clock
        clock = time.perf_counter()

    truth_future = import_ground_truth.submit(store_url, truth) if truth else None
    if cuts is not None:
        shots_ref = given_shots(store_url, {}, {"video": digest, "cuts": [int(c) for c in cuts],
                                                "num_frames": info.num_frames, "fps": info.fps})
    else:
        shots_ref = detect_video_shots(store_url, {}, {"video": digest,
                                                       "config": dataclasses.asdict(ShotConfig(**(shots or {})))}, video)
    lap("shot detection")
    focal_params = {"video": digest, "config": dataclasses.asdict(FocalConfig())}
    motion_ref = None
    if intrinsics is None:  # the focal length from the pixels; perception needs a K first (multithumbs.scene.focal)
        motion_ref = estimate_video_focal(store_url, {"shots": shots_ref}, focal_params, video)
        motion = load(motion_ref)
        if motion.source != "none":
            K = motion.K(info.width, info.height).tolist()
        lap("focal length")
    tracks = perceive_people(store_url, {"shots": shots_ref},
                             {"video": digest, "spec": spec_fingerprint(perception), "trust": trust_pickle, "K": K,
                              "network_kernels": network_kernel_tag(), **body}, video, perception, body_path, device)
    lap("perception")
    if motion_ref is None:
        focal = given_focal(np.asarray(K))
    else:
        focal = load(estimate_video_focal(store_url, {"shots": shots_ref, "motion": motion_ref,
                                                      **{f"tracks_{k}": r for k, r in enumerate(tracks)}},
                                          focal_params, video))
        K = focal.K(info.width, info.height).tolist()  # the tracks keep theirs: the method re-expresses them
    tracking_config = dataclasses.asdict(TrackingConfig(**(tracking or {})))
    trajectories = [f.result() for f in [
        track_shot_camera.submit(store_url, {"shots": shots_ref, "tracks": tracks[k]},
                                 {"video": digest, "shot": k, "K": K, "config": tracking_config}, video)
        for k in range(len(tracks))]]
    lap("camera tracking")
    two_view_config = dataclasses.asdict(TwoViewConfig(**(two_view or {})))
    spaces = [f.result() for f in [
        shared_space.submit(store_url, {"shots": shots_ref, "tracks_before": tracks[c], "tracks_after": tracks[c + 1],
                                        "trajectory_before": trajectories[c], "trajectory_after": trajectories[c + 1]},
                            {"video": digest, "cut": c, "K": K, "config": two_view_config, "neighbour_frames": 2}, video)
        for c in range(len(tracks) - 1)]]
    lap("shared spaces")
    inputs = {"shots": shots_ref, **{f"tracks_{k}": r for k, r in enumerate(tracks)},
              **{f"trajectory_{k}": r for k, r in enumerate(trajectories)},
              **{f"space_{c}": r for c, r in enumerate(spaces)}}
    (method_refs,) = run_method(store_url, [(inputs, method_params(variant, method, body))], timings, body_path)
    clock = time.perf_counter()
    truth_ref = truth_future.result() if truth_future else None
    metrics = evaluate_result(method_refs["result"], truth_ref, body_path) if truth_ref else None
    lap("evaluation")
    backends = {**_backends(store_url, shots_ref, trajectories, spaces, perception), "focal length": focal.line()}
    files = publish_outputs(out_dir, Path(video).stem, variant, video, method_refs, space_refs(inputs), truth_ref,
                            metrics, {"backends": backends, "timings": timings, "variant": variant,
                                      "fallbacks": _fallbacks(spaces), "body_model": body_path or "procedural",
                                      "focal": focal.to_json()},
                            body_path)
    from multithumbs.viz.report import people_by_shot

    return {"metrics": metrics, "files": files, "num_shots": len(tracks), "backends": backends, "timings": timings,
            "focal": focal.to_json(),
            "people": people_by_shot(load(method_refs["result"]))}


def _backends(store_url, shots_ref, trajectories, spaces, perception: str) -> dict[str, str]:
    from tasks.artifacts import load

    return {"shots": load(shots_ref).source, "perception": perception.split(":")[0] if "+" not in perception
            else "+".join(t.split(":")[0] for t in perception.split("+")),
            "camera tracking": ", ".join(sorted({load(r).source for r in trajectories})),
            "shared space": ", ".join(sorted({load(r).source for r in spaces})) or "none (one shot)"}


def _fallbacks(spaces) -> dict[str, str]:
    from tasks.artifacts import load

    fallbacks = {f"cut {c}": load(r).fallback for c, r in enumerate(spaces)}
    return {cut: path for cut, path in fallbacks.items() if path}
