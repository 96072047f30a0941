"""Colours of a result shown beside its ground truth: every result person in the colour of the truth
person the evaluation paired it with.

A result's ids are arbitrary labels: a perfect reconstruction may call the truth's #1 "#0". Coloured
by its own ids, such a result looks like an identity swap in every picture (orange on the left, blue on
the right for the same person). So, when truth is given, each result person takes the colour of its
partner in the evaluation's whole-video pairing (:func:`multithumbs.metrics.alignment.pair_people` on
each frame's camera-frame pelvis, exactly as :func:`multithumbs.metrics.evaluate.score_sequence` calls
it); result people without a partner take colours no truth person uses.

Why the whole-video pairing and not one per shot: a result identity then keeps ONE colour for the whole
video, the colour of the truth person it stands for. A mere relabelling is invisible (every person
looks the same in both panels, in every shot), while a real identity switch at a cut is visible: the
track that followed truth A up to the cut (A's colour) follows B after it, so B's body changes colour
at the cut and the two panels disagree from then on. A pairing made per shot would recolour the
result in each shot to match whoever it covers there and hide exactly that error.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from multithumbs.errors import InputError
from multithumbs.geometry import world_to_camera
from multithumbs.metrics.alignment import Correspondence, pair_people, pelvis
from multithumbs.types import GroundTruth, WorldResult
from multithumbs.viz.palette import id_color

LEGEND = "result coloured by the paired truth person"
"""What the pictures say about the result's colours when truth is drawn beside it."""


@dataclass(frozen=True)
class TruthColouring:
    """Display colours of a result's people.

    Attributes:
        colors: ``(P, 3)`` float RGB in [0, 1], one per result row (``result.person_ids`` order).
        partner: ``(P,)`` int, the true id each result row is paired with, -1 for none.
        legend: one line saying what the colours mean (empty when they are the result's own ids).
    """

    colors: np.ndarray
    partner: np.ndarray
    legend: str = ""


def camera_pelvis(world: WorldResult, joints: np.ndarray) -> np.ndarray:
    """``(P, T, 3)`` pelvis of every person in each frame's own camera coordinates (as the evaluation)."""
    joints = np.asarray(joints, np.float64)
    return pelvis(world_to_camera(joints, np.asarray(world.R, np.float64), np.asarray(world.t, np.float64)))


def pair_with_truth(result: WorldResult, joints: np.ndarray, truth: GroundTruth,
                    true_joints: np.ndarray) -> Correspondence:
    """The evaluation's whole-video pairing of true people with result identities.

    Parameters
    ----------
    result : WorldResult
        The reconstruction.
    joints : (P, T, 24, 3) array
        Its world joints (:func:`multithumbs.export.posed.posed_joints`).
    truth : GroundTruth
        The ground truth, with the same frames.
    true_joints : (G, T, 24, 3) array
        The truth's world joints.

    Returns
    -------
    Correspondence
        ``pred_index[g]`` is the result row standing for true person ``g`` (-1 for none).
    """
    if truth.world.num_frames != result.num_frames:
        raise InputError(f"truth: {truth.world.num_frames} frames, but the result has {result.num_frames}")
    return pair_people(camera_pelvis(result, joints), result.valid, camera_pelvis(truth.world, true_joints),
                       truth.visible)


def unused_colors(count: int, used_ids) -> np.ndarray:
    """``(count, 3)`` colours of the first ``count`` ids not in ``used_ids``: none equals a used id's colour."""
    used = {int(i) for i in np.asarray(used_ids).reshape(-1)}
    free, k = [], 0
    while len(free) < count:
        if k not in used:
            free.append(id_color(k))
        k += 1
    return np.stack(free) if free else np.zeros((0, 3))


def own_colouring(result: WorldResult) -> TruthColouring:
    """Colours of the result's own ids (no truth to compare with)."""
    ids = np.asarray(result.person_ids)
    colors = np.stack([id_color(i) for i in ids]) if ids.size else np.zeros((0, 3))
    return TruthColouring(colors, np.full(len(ids), -1, np.int64), "")


def truth_colouring(result: WorldResult, truth: GroundTruth, pairing: Correspondence) -> TruthColouring:
    """Colour every result row by its paired truth person (module docstring).

    Parameters
    ----------
    result : WorldResult
        The reconstruction.
    truth : GroundTruth
        The ground truth the pairing was made against.
    pairing : Correspondence
        :func:`pair_with_truth` (or the evaluation's ``SequenceScores.correspondence``).
    """
    true_ids = np.asarray(truth.world.person_ids)
    partner = np.full(result.num_people, -1, np.int64)
    for g, row in enumerate(np.asarray(pairing.pred_index)):
        if row >= 0:
            partner[row] = int(true_ids[g])
    colors = np.zeros((result.num_people, 3))
    for row, gid in enumerate(partner):
        if gid >= 0:
            colors[row] = id_color(int(gid))
    lonely = np.nonzero(partner < 0)[0]
    colors[lonely] = unused_colors(len(lonely), true_ids)
    return TruthColouring(colors, partner, LEGEND)


def colouring_for(result: WorldResult, joints: np.ndarray, truth: GroundTruth | None = None,
                  true_joints: np.ndarray | None = None) -> TruthColouring:
    """:func:`truth_colouring` of the evaluation's pairing when truth is given, else :func:`own_colouring`."""
    if truth is None:
        return own_colouring(result)
    if true_joints is None:
        raise InputError("true_joints: required with truth")
    return truth_colouring(result, truth, pair_with_truth(result, joints, truth, true_joints))
