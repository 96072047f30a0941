"""Global identities (paper §3.4): fragments of one person linked within each shot, then people matched
across every cut.

Within a shot a tracker loses a person behind someone else and finds them again under a new id; each such
return is an identity switch. Once every track has its world root (:class:`~multithumbs.world_placement.
Placement`), :func:`link_fragments` treats the gap between the end of one track and the start of a later
one in the same shot as a cut is treated: the fused cost U of §3.4 (root distance, appearance, pose),
Hungarian, the distance gate widened by walking speed over the gap (with the earlier root carried along
its walk over it, :func:`walking_velocity`), and an appearance gate, since within
a shot nothing else says two fragments are one person. :func:`reidentify` then matches people across
cuts, each chain of linked fragments as one person: its first fragment after a cut, its last before one.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
from scipy.optimize import linear_sum_assignment

from multithumbs.appearance import mean_descriptor
from multithumbs.method.config import ReidConfig
from multithumbs.method.reid import Candidates, Matching, distance_gate, fused_cost, match_people
from multithumbs.types import PersonTracks
from multithumbs.world_placement import Placement


@dataclass(frozen=True)
class Identities:
    """Global identities.

    Attributes:
        global_ids: per shot ``(P_s,)`` int global id of every track; tracks of one shot share an id when
            they were linked as fragments of one person (their frames never overlap).
        matchings: per cut, the re-ID outcome (before side: candidates listed in ``before_ids``).
        before_ids: per cut ``(N,)`` global ids of the candidates before the cut.
        matched_at_cut: ``(G, C)`` bool, person matched across cut ``c``.
    """

    global_ids: tuple[np.ndarray, ...]
    matchings: tuple[Matching, ...]
    before_ids: tuple[np.ndarray, ...]
    matched_at_cut: np.ndarray

    @property
    def num_people(self) -> int:
        return int(max((g.max() + 1 for g in self.global_ids if len(g)), default=0))


def _candidate(tr: PersonTracks, placement_pelvis: np.ndarray, i: int, frame: int, window: np.ndarray,
               min_conf: float) -> tuple:
    """``(root, appearance, body_pose, joint_visible, video_frame)`` of track ``i`` at shot-local ``frame``."""
    appearance = mean_descriptor(tr.appearance[i, window], tr.appearance_valid[i, window])
    visible = tr.keypoints2d[i, frame, 1:24, 2] > min_conf if tr.keypoints2d.shape[2] >= 24 else np.ones(23, bool)
    return placement_pelvis[i, frame], appearance, tr.body_pose[i, frame], visible, tr.start_frame + frame


def _candidates(rows: Sequence[tuple], gap: np.ndarray | None = None, known: np.ndarray | None = None,
                velocity: np.ndarray | None = None) -> Candidates:
    def stack(j):
        return np.stack([np.asarray(r[j]) for r in rows])
    return Candidates(stack(0), stack(1), stack(2), stack(3), gap=gap, distance_known=known, velocity=velocity)


def walking_velocity(pelvis: np.ndarray, frames: np.ndarray, fps: float, config: ReidConfig) -> np.ndarray:
    """``(3,)`` m/s: the least-squares slope of a track's world root over its observed ``frames`` in the last
    ``config.motion_window`` seconds before the latest, its norm at most ``config.max_speed``; zero with
    fewer than 5 such frames or a window of 0 (a person standing, or too little seen to tell).

    Args:
        pelvis: ``(T, 3)`` the track's world roots; frames: ``(F,)`` increasing indices of its observed frames.
    """
    if config.motion_window <= 0 or len(frames) == 0:
        return np.zeros(3)
    recent = frames[frames >= frames[-1] - config.motion_window * fps]
    if len(recent) < 5:
        return np.zeros(3)
    t = recent / fps - (recent / fps).mean()
    x = pelvis[recent] - pelvis[recent].mean(0)
    v = (t[:, None] * x).sum(0) / (t ** 2).sum()
    speed = float(np.linalg.norm(v))
    return v * (config.max_speed / speed) if speed > config.max_speed else v


def link_fragments(tracks: PersonTracks, pelvis: np.ndarray, config: ReidConfig, appearance_window: int = 15,
                   fps: float = 30.0) -> np.ndarray:
    """Which earlier track of the same shot each track continues (module docstring).

    Args:
        tracks: one shot's tracks (a track with no valid frame is never linked).
        pelvis: ``(P, T, 3)`` their world pelvis positions (:attr:`Placement.pelvis` of the shot).
        config: the cost's weights and gates; ``link_gap`` seconds at most between the two fragments
            (0: no links), ``link_appearance`` the largest appearance dissimilarity of a link.
        appearance_window: detections averaged for each fragment's appearance next to the gap.
        fps: frames per second.
    Returns:
        ``(P,)`` int, the index of the track that track ``i`` continues, -1 for none. Each track continues
        at most one and is continued by at most one; a track starts after the one it continues has ended.
    """
    P = tracks.num_people
    previous = np.full(P, -1, np.int64)
    if P < 2 or config.link_gap <= 0:
        return previous
    seen = [np.flatnonzero(tracks.valid[i]) for i in range(P)]
    present = np.array([len(f) > 0 for f in seen])
    first = np.array([f[0] if len(f) else 0 for f in seen])
    last = np.array([f[-1] if len(f) else 0 for f in seen])
    frames_between = first[None, :] - last[:, None]  # (ending track, starting track); >= 1: one after the other
    feasible = (frames_between >= 1) & (frames_between <= round(config.link_gap * fps))
    feasible &= present[:, None] & present[None, :]  # a track never seen links to nothing
    if not feasible.any():
        return previous
    c = config.keypoint_confidence
    ends = _candidates([_candidate(tracks, pelvis, i, last[i], seen[i][-appearance_window:], c) for i in range(P)],
                       velocity=np.stack([walking_velocity(pelvis[i], seen[i], fps, config) for i in range(P)]))
    starts = _candidates([_candidate(tracks, pelvis, i, first[i], seen[i][:appearance_window], c) for i in range(P)])
    elapsed = np.maximum(frames_between, 0) / fps
    cost, distance, appearance, _, known = fused_cost(ends, starts, config, elapsed)
    gate = distance_gate(elapsed, config)  # as at a cut: τ widened by the gap
    allowed = feasible & ((distance <= gate) | ~known) & (appearance <= config.link_appearance)
    if not allowed.any():
        return previous
    # Pairs outside the gates cost more than any chain of allowed ones could save.
    rows, cols = linear_sum_assignment(np.where(allowed, cost, cost[allowed].max() * P + 1.0))
    for a, b in zip(rows, cols):
        if allowed[a, b]:
            previous[b] = a
    return previous


def reidentify(tracks: Sequence[PersonTracks], placement: Placement, config: ReidConfig,
               appearance_window: int = 15, fps: float = 30.0) -> Identities:
    """Assign global ids: fragments linked within each shot (:func:`link_fragments`), then cut by cut;
    people absent on one side keep their ids for later shots."""
    n_shots = len(tracks)
    links = [link_fragments(tr, placement.pelvis[k], config, appearance_window, fps) for k, tr in enumerate(tracks)]
    global_ids = [np.full(tr.num_people, -1) for tr in tracks]

    def new_ids(k: int, next_id: int) -> int:
        """Give shot ``k``'s unassigned chain heads new ids, in track order, and every linked fragment its
        chain's id."""
        for i in range(tracks[k].num_people):
            if links[k][i] < 0 and global_ids[k][i] < 0:
                global_ids[k][i] = next_id
                next_id += 1
        for i in range(tracks[k].num_people):
            head = i
            while links[k][head] >= 0:
                head = links[k][head]
            global_ids[k][i] = global_ids[k][head]
        return next_id

    next_id = new_ids(0, 0)
    last_state: dict[int, tuple] = {}  # gid -> candidate tuple at its last appearance
    last_shot: dict[int, int] = {}     # gid -> the shot it was last seen in
    last_velocity: dict[int, np.ndarray] = {}  # gid -> its world root's velocity there
    reliable = placement.distance_reliable if placement.distance_reliable is not None \
        else np.ones(n_shots - 1, bool)
    matchings, before_ids = [], []
    matched = []
    for k in range(n_shots - 1):
        tr, nxt = tracks[k], tracks[k + 1]
        ending = [(np.flatnonzero(tr.valid[i])[-1], i) for i in range(tr.num_people) if tr.valid[i].any()]
        for last, i in sorted(ending):  # a chain's last fragment is its state at the cut
            frames = np.flatnonzero(tr.valid[i])
            last_state[int(global_ids[k][i])] = _candidate(
                tr, placement.pelvis[k], i, last, frames[-appearance_window:], config.keypoint_confidence)
            last_shot[int(global_ids[k][i])] = k
            last_velocity[int(global_ids[k][i])] = walking_velocity(placement.pelvis[k][i], frames, fps, config)
        before = sorted(last_state)
        after = []
        for i in range(nxt.num_people):  # a chain's first fragment stands for it after the cut
            frames = np.flatnonzero(nxt.valid[i])
            after.append(_candidate(nxt, placement.pelvis[k + 1], i, frames[0], frames[:appearance_window],
                                    config.keypoint_confidence) if len(frames) and links[k + 1][i] < 0 else None)
        cut_frame = nxt.start_frame
        rows_b = [last_state[g] for g in before]
        rows_a = [r for r in after if r is not None]
        idx_a = [i for i, r in enumerate(after) if r is not None]
        if rows_b and rows_a:
            # Seconds between each observation and the cut: the gate widens with them.
            # D is known for someone last seen in shot s when every cut from s to this one placed its cameras.
            known = np.array([bool(reliable[last_shot[g]:k + 1].all()) for g in before])
            cand_b = _candidates(rows_b, (cut_frame - 1 - np.array([r[4] for r in rows_b])) / fps, known,
                                 np.stack([last_velocity[g] for g in before]))
            cand_a = _candidates(rows_a, (np.array([r[4] for r in rows_a]) - cut_frame) / fps)
            matching = match_people(cand_b, cand_a, config)
        else:
            empty = np.zeros((len(rows_b), len(rows_a)))
            matching = Matching(np.zeros((0, 2), np.int64), empty, empty, empty, empty)
        pairs_now = set()
        for bi, ai in matching.pairs:
            global_ids[k + 1][idx_a[ai]] = before[bi]
            pairs_now.add(before[bi])
        next_id = new_ids(k + 1, next_id)
        matchings.append(matching)
        before_ids.append(np.asarray(before, dtype=np.int64))
        matched.append(pairs_now)
    matched_at_cut = np.zeros((next_id, n_shots - 1), bool)
    for c, gids in enumerate(matched):
        for g in gids:
            matched_at_cut[g, c] = True
    return Identities(tuple(global_ids), tuple(matchings), tuple(before_ids), matched_at_cut)


__all__ = ["Identities", "link_fragments", "reidentify", "walking_velocity"]
