"""Metrics of docs/METRICS.md: pose, camera, identity and ground-truth-free, and the evaluation that runs them all.

Low-level functions take numpy arrays in metres (``(P, T, 24, 3)`` joints with ``valid (P, T)``
masks) and return :class:`Samples` so sequences pool frame-weighted; :func:`evaluate` and
:func:`evaluate_sequences` score :class:`~multithumbs.types.WorldResult` against
:class:`~multithumbs.types.GroundTruth`.
"""

from multithumbs.metrics.alignment import (
    Correspondence, Samples, ValidFrames, apply_similarity, fit_similarity, pair_people, pelvis,
    track_similarities, apply_track_similarities, window_mask,
)
from multithumbs.metrics.camera import TrajectoryError, absolute_trajectory_error, centre_rank
from multithumbs.metrics.evaluate import (
    EvaluationOptions, SequenceScores, body_points, evaluate, evaluate_sequences, score_sequence, summarize,
)
from multithumbs.metrics.gt_free import (
    CrossShotPck, cross_shot_pck, estimate_up, foot_points, foot_sliding, jitter,
)
from multithumbs.metrics.identity import (
    IdSwitches, associate_by_distance, associate_by_iou, box_iou, clear_mot_match, count_id_switches,
    projected_boxes,
)
from multithumbs.metrics.pose import (
    WORLD_CHUNK, accel, accel_world, foot_sliding_against_truth, mpjpe, mpvpe, pa_mpjpe, w_mpjpe, wa_mpjpe,
    world_aligned,
)

__all__ = [
    "Correspondence", "Samples", "ValidFrames", "apply_similarity", "fit_similarity", "pair_people", "pelvis",
    "track_similarities", "apply_track_similarities", "window_mask",
    "TrajectoryError", "absolute_trajectory_error", "centre_rank",
    "EvaluationOptions", "SequenceScores", "body_points", "evaluate", "evaluate_sequences",
    "score_sequence", "summarize",
    "CrossShotPck", "cross_shot_pck", "estimate_up", "foot_points", "foot_sliding", "jitter",
    "IdSwitches", "associate_by_distance", "associate_by_iou", "box_iou", "count_id_switches",
    "clear_mot_match", "projected_boxes",
    "WORLD_CHUNK", "accel", "accel_world", "foot_sliding_against_truth", "mpjpe", "mpvpe", "pa_mpjpe",
    "w_mpjpe", "wa_mpjpe", "world_aligned",
]
