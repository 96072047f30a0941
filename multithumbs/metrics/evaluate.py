"""Score a reconstruction against ground truth with every metric of docs/METRICS.md.

Coordinate frames, since the predicted world frame is arbitrary:

- pairing of identities, MPJPE, PA-MPJPE, MPVPE and the root-distance ID association use each frame's
  camera coordinates (prediction through its predicted camera, truth through the true camera): they
  need no alignment and do not depend on the prediction's world frame. The ``*_world`` variants are the
  same errors without root alignment, i.e. the prediction placed in the true world through that frame's
  true camera.
- ``accel`` (the field's Accel, m/s^2) uses the pelvis-aligned camera-frame joints, as WHAM/GVHMR.
- W-MPJPE and WA-MPJPE use world joints after a per-person Sim(3) per chunk of 100 valid frames
  (first two frames, or the whole chunk); ``*_track`` use one chunk per track. ``accel_world``
  (mm/frame^2) uses the whole-track WA alignment, so a jump at a cut is not hidden by re-alignment.
- ``fs_gt`` (foot sliding with truth, GVHMR) takes the predicted foot points as predicted, in the
  prediction's world, where the true feet rest.
- ATE aligns each sequence's camera centres with one Sim(3) (or, when they are degenerate, the Sim(3)
  fitted on all people's joints; ``ate_alignment`` says which).
- IDs associate per frame as TrackEval's CLEAR-MOT does, on 2D boxes (or 3D roots).
- PCK*, Jitter and FS (the ``fs`` key) read only the reconstruction.

Where a reference masks invalid frames (WHAM, GVHMR) it drops them and treats the rest as consecutive:
the chunked world errors, ``accel``, ``fs_gt`` and Jitter do the same.

The body model runs once per reconstruction and once per truth, over all people and frames at once.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any, Sequence

import numpy as np
import torch

from multithumbs.conventions import NUM_BETAS, NUM_JOINTS
from multithumbs.errors import InputError
from multithumbs.geometry import camera_centre, world_to_camera
from multithumbs.metrics.alignment import (
    Correspondence, Samples, apply_track_similarities, fit_similarity, pair_people, pelvis,
    track_similarities,
)
from multithumbs.metrics.camera import TrajectoryError, absolute_trajectory_error
from multithumbs.metrics.gt_free import (
    mean_of_directions, cross_shot_pck, estimate_up, foot_points, foot_sliding, jitter,
)
from multithumbs.metrics.identity import (
    IdSwitches, associate_by_distance, associate_by_iou, count_id_switches, projected_boxes,
)
from multithumbs.metric_names import METRIC_UNITS, report_rows  # noqa: F401  (re-exported)
from multithumbs.metrics.options import EvaluationOptions
from multithumbs.metrics.pose import (
    accel, accel_world, foot_sliding_against_truth, mpjpe, mpvpe, pa_mpjpe, w_mpjpe, wa_mpjpe,
)
from multithumbs.types import GroundTruth, WorldResult

PCK_ALPHA_STRICT = 0.05
"""The stricter PCK* threshold, always reported as ``pck_005``."""


@dataclass(frozen=True)
class SequenceScores:
    """What one sequence contributes to a report, before pooling.

    Attributes:
        samples: per-sample values by name (pose errors per frame, Accel per triplet, ATE per
            frame, PCK* per joint and direction...), pooled frame-weighted across sequences.
        correspondence: the pairing of true people with predicted identities.
        id_switches: CLEAR-MOT switches.
        ate: the camera trajectory error, None when it could not be computed (see ``notes``).
        notes: metric name -> why it is NaN or how it was computed.
        switch_events: every switch (:meth:`IdSwitches.events`): frame, true person, ids, cut.
    """

    samples: dict[str, Samples]
    correspondence: Correspondence
    id_switches: IdSwitches
    ate: TrajectoryError | None
    notes: dict[str, str] = field(default_factory=dict)
    switch_events: list[dict[str, int]] = field(default_factory=list)


def body_points(body_model: Any, world: WorldResult) -> tuple[np.ndarray, np.ndarray]:
    """Run the body model once over all people and frames.

    Args:
        body_model: has ``forward(global_orient, body_pose, betas, transl)`` returning ``.joints
            (..., 24, 3)`` and ``.vertices (..., V, 3)``, and ``num_vertices``; optional ``dtype``.
        world: the people to pose.
    Returns:
        ``joints (P, T, 24, 3)`` and ``vertices (P, T, V, 3)``, float64 metres.
    """
    p, t = world.valid.shape
    if p == 0:
        return np.zeros((0, t, NUM_JOINTS, 3)), np.zeros((0, t, int(body_model.num_vertices), 3))
    dtype = getattr(body_model, "dtype", torch.float32)
    as_tensor = lambda a: torch.as_tensor(np.ascontiguousarray(a), dtype=dtype)
    betas = np.broadcast_to(world.betas[:, None, :], (p, t, NUM_BETAS))
    with torch.no_grad():
        out = body_model.forward(as_tensor(world.global_orient), as_tensor(world.body_pose),
                                 as_tensor(betas), as_tensor(world.transl))
    joints = out.joints.detach().cpu().numpy().astype(np.float64)
    vertices = out.vertices.detach().cpu().numpy().astype(np.float64)
    if joints.shape != (p, t, NUM_JOINTS, 3) or vertices.shape[:2] != (p, t):
        raise InputError(f"body_model: expected joints {(p, t, NUM_JOINTS, 3)} and vertices {(p, t, 'V', 3)}, "
                         f"got {joints.shape} and {vertices.shape}")
    return joints, vertices


def score_sequence(result: WorldResult, truth: GroundTruth, body_model: Any,
                   options: EvaluationOptions = EvaluationOptions()) -> SequenceScores:
    """Every metric's samples for one reconstruction of one video (see :func:`evaluate`)."""
    if result.num_frames != truth.world.num_frames:
        raise InputError(f"result: {result.num_frames} frames but the ground truth has {truth.world.num_frames}")
    notes: dict[str, str] = {}
    pred_joints, pred_vertices = body_points(body_model, result)
    true_joints, true_vertices = body_points(body_model, truth.world)
    if pred_vertices.shape[2] != true_vertices.shape[2]:
        raise InputError(f"body_model: {pred_vertices.shape[2]} vertices for the result but "
                         f"{true_vertices.shape[2]} for the truth")
    true_cuts = truth.world.cut_frames

    # Camera coordinates: comparable frame by frame whatever the predicted world frame.
    pred_joints_cam = world_to_camera(pred_joints, result.R, result.t)
    pred_vertices_cam = world_to_camera(pred_vertices, result.R, result.t)
    true_joints_cam = world_to_camera(true_joints, truth.world.R, truth.world.t)
    true_vertices_cam = world_to_camera(true_vertices, truth.world.R, truth.world.t)

    pairing = pair_people(pelvis(pred_joints_cam), result.valid, pelvis(true_joints_cam), truth.visible)
    scored = pairing.scored
    paired_joints, paired_joints_cam = pairing.gather(pred_joints), pairing.gather(pred_joints_cam)
    paired_vertices_cam = pairing.gather(pred_vertices_cam)
    switches, switch_events = _id_switches(result, truth, options, pred_joints_cam, pred_vertices_cam,
                                           true_joints_cam, true_vertices_cam)

    samples = {
        "mpjpe": mpjpe(paired_joints_cam, true_joints_cam, scored, root_align=options.root_align),
        "mpjpe_world": mpjpe(paired_joints_cam, true_joints_cam, scored, root_align=False),
        "pa_mpjpe": pa_mpjpe(paired_joints_cam, true_joints_cam, scored),
        "mpvpe": mpvpe(paired_vertices_cam, true_vertices_cam, paired_joints_cam, true_joints_cam, scored,
                       root_align=options.root_align),
        "mpvpe_world": mpvpe(paired_vertices_cam, true_vertices_cam, paired_joints_cam, true_joints_cam,
                             scored, root_align=False),
        "w_mpjpe": w_mpjpe(paired_joints, true_joints, scored, chunk=options.chunk),
        "wa_mpjpe": wa_mpjpe(paired_joints, true_joints, scored, chunk=options.chunk),
        "w_mpjpe_track": w_mpjpe(paired_joints, true_joints, scored, chunk=None),
        "wa_mpjpe_track": wa_mpjpe(paired_joints, true_joints, scored, chunk=None),
        "accel": accel(paired_joints_cam, true_joints_cam, scored, truth.world.fps),
    }
    del pred_vertices_cam, paired_vertices_cam, true_vertices_cam

    # accel_world: world joints under the whole-track WA alignment of each person, so a jump at a cut
    # is not hidden by re-alignment.
    track_sim, _ = track_similarities(paired_joints, true_joints, scored, "all")
    aligned_joints = apply_track_similarities(track_sim, paired_joints, scored)
    samples["accel_world"] = accel_world(aligned_joints, true_joints, scored, true_cuts, options.include_cuts)
    foot_ids = getattr(body_model, "foot_vertex_ids", None)
    pred_feet = foot_points(pred_joints, pred_vertices, foot_ids)
    true_feet = foot_points(true_joints, true_vertices, foot_ids)
    samples["fs_gt"] = foot_sliding_against_truth(pairing.gather(pred_feet), true_feet, scored,
                                                  options.contact_speed)

    ate = _camera_error(result, truth, paired_joints, true_joints, scored, notes)
    if ate is not None:
        samples["ate"] = ate.errors

    samples.update(_gt_free(result, pred_joints, pred_feet, options, notes))
    if truth.visible.any():
        # The same ground-truth-free FS on the truth's own motion: the value a perfect reconstruction gets
        # (a real capture's or a procedural walk's feet are never perfectly still), to read ``fs`` against.
        up = np.asarray(options.up) if options.up is not None else estimate_up(true_joints, truth.visible)
        samples["fs_truth"] = foot_sliding(true_feet, truth.visible, up, true_cuts, options.contact_height,
                                           options.ground_percentile)
    return SequenceScores(samples, pairing, switches, ate, notes, switch_events)


def _camera_error(result: WorldResult, truth: GroundTruth, paired_joints: np.ndarray, true_joints: np.ndarray,
                  scored: np.ndarray, notes: dict[str, str]) -> TrajectoryError | None:
    """ATE with the shared joint-based WA alignment as the fallback for degenerate centres."""
    shared, fitted = fit_similarity(paired_joints[scored].reshape(-1, 3), true_joints[scored].reshape(-1, 3))
    fallback = shared if bool(fitted) else None
    try:
        ate = absolute_trajectory_error(camera_centre(result.R, result.t),
                                        camera_centre(truth.world.R, truth.world.t),
                                        fallback_alignment=fallback)
    except InputError as error:
        notes["ate"] = f"not computed: {error}"
        return None
    if ate.fallback:
        notes["ate"] = (f"camera centres degenerate (cross-covariance rank {ate.centre_rank}): aligned with "
                        "the Sim(3) fitted on all people's joints")
    return ate


ATE_ALIGNMENTS = {False: "sim3_camera_centres", True: "sim3_people_joints"}
"""How a sequence's ATE was aligned: Umeyama on the camera centres, or (degenerate centres) the WA
Sim(3) fitted on all people's joints."""


def _id_switches(result: WorldResult, truth: GroundTruth, options: EvaluationOptions,
                 pred_joints_cam: np.ndarray, pred_vertices_cam: np.ndarray, true_joints_cam: np.ndarray,
                 true_vertices_cam: np.ndarray) -> tuple[IdSwitches, list[dict[str, int]]]:
    """Per-frame CLEAR-MOT association (box IoU or root distance), the switches and each one's details."""
    if options.id_association == "box_iou":
        # Predicted boxes: the predicted mesh projected by the predicted camera, clipped to the image, so
        # amodal (the whole body, occluded parts too); the true boxes must be the same kind.
        boxes, in_image = projected_boxes(pred_vertices_cam, result.K, result.image_size)
        if options.truth_boxes == "mesh":
            true_boxes, _ = projected_boxes(true_vertices_cam, truth.world.K, truth.world.image_size)
        else:
            true_boxes = truth.bboxes
        matched = associate_by_iou(true_boxes, truth.visible, boxes, result.valid & in_image, options.min_iou)
    else:
        matched = associate_by_distance(pelvis(true_joints_cam), truth.visible, pelvis(pred_joints_cam),
                                        result.valid, options.max_root_distance)
    switches = count_id_switches(matched, result.person_ids, truth.world.cut_frames)
    return switches, switches.events(matched, result.person_ids)


def _gt_free(result: WorldResult, pred_joints: np.ndarray, pred_feet: np.ndarray, options: EvaluationOptions,
             notes: dict[str, str]) -> dict[str, Samples]:
    """PCK*, Jitter and height-based FS from the reconstruction alone."""
    out = {"jitter": jitter(pred_joints, result.valid, result.fps, result.cut_frames, options.include_cuts)}
    keypoints = result.keypoints2d
    if keypoints is None:
        notes["pck"] = "result.keypoints2d is None: PCK* needs the observed 2D keypoints"
    elif keypoints.shape[2] != NUM_JOINTS:
        notes["pck"] = f"result.keypoints2d has {keypoints.shape[2]} keypoints: PCK* needs the 24 SMPL-order ones"
    elif not len(result.cut_frames):
        notes["pck"] = "single-shot video: PCK* is measured across cuts"
    else:
        for key, alpha in (("pck", options.pck_alpha), ("pck_005", PCK_ALPHA_STRICT)):
            pck = cross_shot_pck(pred_joints, result.valid, keypoints, result.K, result.R, result.t,
                                 result.cut_frames, alpha, options.min_keypoint_confidence)
            out[f"{key}_forward"], out[f"{key}_backward"] = pck.forward, pck.backward
    if "pck" in notes:
        notes["pck_005"] = notes["pck"]
    if options.up is not None:
        up = np.asarray(options.up)
    elif result.valid.any():
        up = estimate_up(pred_joints, result.valid)
    else:
        up = None
        notes["fs"] = "no valid body in the result"
    if up is not None:
        out["fs"] = foot_sliding(pred_feet, result.valid, up, result.cut_frames, options.contact_height,
                                 options.ground_percentile)
    return out


POOLED_MEANS = ("w_mpjpe", "wa_mpjpe", "mpjpe", "pa_mpjpe", "mpvpe", "accel", "jitter", "fs",
                "mpjpe_world", "mpvpe_world", "w_mpjpe_track", "wa_mpjpe_track", "accel_world", "fs_gt", "fs_truth")
"""Metrics reported as the mean of their pooled samples."""


def summarize(scores: Sequence[SequenceScores], options: EvaluationOptions) -> dict[str, Any]:
    """Pool sequences into the report: frame-weighted means; ATE and IDs per sequence, then averaged.

    Returns:
        a flat dict of the headline metrics ``w_mpjpe, wa_mpjpe`` (chunks of 100 valid frames), ``mpjpe,
        pa_mpjpe, mpvpe`` (mm), ``accel`` (m/s^2), ``ate`` (m: mean over sequences of each one's RMSE,
        as DROID-SLAM and TRAM report), ``ids`` (switches per sequence, averaged over sequences), ``pck``
        (%), ``jitter`` (10 m/s^3), ``fs`` (mm/frame); this project's own ``w_mpjpe_track,
        wa_mpjpe_track`` (one chunk per track, mm), ``accel_world`` (mm/frame^2), ``fs_gt`` (mm),
        ``fs_truth`` (``fs`` of the truth's own motion, the reference a perfect result reaches, mm/frame),
        ``mpjpe_world, mpvpe_world`` (mm); and ``ate_mean`` (mean over sequences of each one's mean
        error), ``ate_per_sequence``, ``ate_alignment`` (per sequence: ``sim3_camera_centres`` or
        ``sim3_people_joints``), ``ate_fallback`` (any sequence used the joints), ``ids_total``,
        ``ids_per_sequence``, ``ids_per_cut`` (all switches / all cuts), ``ids_at_cuts`` (per sequence,
        switches through each cut), ``ids_within_shots``, ``id_switch_events`` (per sequence, every switch's
        frame, true person, ids and cut), ``coverage, pck_005, num_sequences,
        scored_frames, notes, options``.
    """
    if not scores:
        raise InputError("sequences: nothing to evaluate")

    def pooled(name: str) -> Samples:
        return Samples.concatenate([s.samples[name] for s in scores if name in s.samples])

    report: dict[str, Any] = {name: pooled(name).mean() for name in POOLED_MEANS}
    trajectories = [s.ate for s in scores]
    rmse = [float("nan") if a is None else a.rmse for a in trajectories]
    report["ate"] = _mean_of_finite(rmse)
    report["ate_mean"] = _mean_of_finite([float("nan") if a is None else a.mean for a in trajectories])
    report["ate_per_sequence"] = rmse
    report["ate_alignment"] = [None if a is None else ATE_ALIGNMENTS[a.fallback] for a in trajectories]
    report["ate_fallback"] = any(a is not None and a.fallback for a in trajectories)
    totals = [s.id_switches.total for s in scores]
    cuts = sum(s.id_switches.num_cuts for s in scores)
    report["ids"] = float(np.mean(totals))
    report["ids_total"] = int(sum(totals))
    report["ids_per_sequence"] = totals
    report["ids_per_cut"] = sum(totals) / cuts if cuts else float("nan")
    report["ids_at_cuts"] = [s.id_switches.at_cuts for s in scores]
    report["ids_within_shots"] = int(sum(s.id_switches.within_shots for s in scores))
    report["id_switch_events"] = [s.switch_events for s in scores]
    for key in ("pck", "pck_005"):
        report[key] = mean_of_directions(pooled(f"{key}_forward").mean(), pooled(f"{key}_backward").mean())
    visible = sum(int(s.correspondence.visible.sum()) for s in scores)
    scored = sum(int(s.correspondence.scored.sum()) for s in scores)
    report["coverage"] = scored / visible if visible else float("nan")
    report["scored_frames"] = scored
    report["num_sequences"] = len(scores)
    notes: dict[str, str] = {}
    for index, s in enumerate(scores):
        for key, note in s.notes.items():
            text = note if len(scores) == 1 else f"sequence {index}: {note}"
            notes[key] = f"{notes[key]}; {text}" if key in notes else text
    for name in (*POOLED_MEANS, "ate", "pck", "pck_005"):
        if np.isnan(report[name]) and name not in notes:
            notes[name] = "no samples to score (nothing valid, visible or in contact)"
    report["notes"] = notes
    report["options"] = asdict(options)
    return report


def _mean_of_finite(values: Sequence[float]) -> float:
    finite = [v for v in values if np.isfinite(v)]
    return float(np.mean(finite)) if finite else float("nan")


def evaluate(result: WorldResult, truth: GroundTruth, body_model: Any, **options: Any) -> dict[str, Any]:
    """Score one reconstruction against its ground truth with every metric of docs/METRICS.md.

    Args:
        result: the reconstruction (any world frame).
        truth: the ground truth.
        body_model: see :func:`body_points`; ``foot_vertex_ids`` (None or indices) picks the foot points.
        **options: fields of :class:`EvaluationOptions`.
    Returns:
        the report of :func:`summarize`. Missing inputs give NaN with a reason in ``notes`` (e.g.
        ``pck`` without ``result.keypoints2d``).
    """
    opts = EvaluationOptions.from_kwargs(options)
    return summarize([score_sequence(result, truth, body_model, opts)], opts)


def evaluate_sequences(pairs: Sequence[tuple[WorldResult, GroundTruth]], body_model: Any,
                       **options: Any) -> dict[str, Any]:
    """Score several sequences and pool them: pose errors over all scored frames of all people of all
    sequences (frame-weighted), ATE and IDs per sequence then averaged. Options as :func:`evaluate`."""
    opts = EvaluationOptions.from_kwargs(options)
    if not pairs:
        raise InputError("sequences: nothing to evaluate")
    return summarize([score_sequence(result, truth, body_model, opts) for result, truth in pairs], opts)
