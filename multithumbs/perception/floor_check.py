"""Short tracks whose feet are not on the floor the shot's other people stand on: readings of no one.

BlazePose reads bodies into patterns: a patterned rug, or a whole small body inside the torso of a person
close to the camera and cut by the frame's edge. On the standard suite's pixels, 5 tracks (45 of 3451
readings) were more than 100 px from every true person's joints in every frame; a real person took one's
identity at a cut, and another gave its id to the person whose torso it was in (``docs/RESULTS.md``,
sessions 27 and 28). Neither their masks nor their boxes' proportions tell them from people. Where they
stand does.

A point on the floor at camera-frame depth ``Z`` and image column ``u`` projects to the row
``v = a + b / Z + c u`` (the plane ``n · X = d`` seen by a pinhole camera, solved for ``v``: ``c`` is the
camera's roll, zero for a level one). People standing on one floor put their feet on that surface at the
depth their fitted body is at. So the shot's readings with visible feet, each with the row of its lowest
foot, its column and its fitted root's depth, give the floor's ``a, b, c`` (a robust least-squares fit,
``scipy.optimize.least_squares`` with a soft-L1 loss, on every other track's readings). A reading's
offset is its foot row's distance from that surface, in units of its own keypoints' height. On the suite,
the short real tracks' median offsets were at most 0.14, the five tracks of no one's 0.41-2.80.

A floor is only as good as the others' feet fit it. On OpenCV's ``vtest.avi`` (pedestrians on grass and
paths, small and far) the other readings' offsets scatter by 0.29 of their heights, against 0.02-0.09 on
the suite's flat rooms, and a real walker there was 0.44 off. So a track is dropped only when its offset is also many
times (``min_scatters``) the others' own scatter about the floor (1.4826 times their median absolute
deviation): the suite's tracks of no one were 9.8-104 times it, its people and vtest's at most 3.1.

Only short tracks are judged (``max_readings``): a person followed for a long time is a person, and the
check must not take someone standing on a stair or a stage for a pattern. Every track of no one on the
suite was read in at most 16 frames, and long real tracks judged against one or two others reached 0.54,
where so few people fit the floor loosely.

Nor are tracks whose mask reaches the frame's edge in any reading (``judge_cut``): a person walking in or
out through the edge, or close to the camera and cut by it. Their tracks are short because the frame cuts
them, and BlazePose squeezes the body it reads into the frame, so the feet land inside the image, above
where the person stands. On the suite at stage 31 the check dropped four tracks: two readings of no one,
never at the frame's edge, and two people entering (s01, s02), whose masks were at the edge in 86 % and
38 % of their readings and whose feet were read 0.30 and 0.32 of their heights off the floor.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from multithumbs.types import PersonTracks

FOOT_JOINTS: tuple[int, ...] = (7, 8, 10, 11)
"""SMPL's ankles and feet."""


@dataclass(frozen=True)
class FloorCheckConfig:
    """Which tracks are judged against the shot's floor, and when they are dropped (module docstring)."""

    enabled: bool = True
    """Drop the short tracks whose feet are off the floor."""
    max_readings: int = 24
    """Tracks read in at most this many frames (1 s at 24 fps) are judged; longer ones are people."""
    max_offset: float = 0.25
    """Median offset of a track's feet from the floor, in its keypoints' heights, above which it is dropped
    (suite: short tracks of people 0.14 at most, tracks of no one 0.41 at least)."""
    min_scatters: float = 5.0
    """How many times the other readings' own scatter about the floor the offset must also exceed."""
    min_floor_readings: int = 20
    """Readings with visible feet the other tracks need for their floor to be fitted."""
    min_floor_tracks: int = 2
    """Other tracks with visible feet the floor needs: one person's readings leave it free to tilt."""
    min_depth_spread: float = 0.2
    """Spread of the other readings' inverse depths (max - min, over their median) the floor needs: feet
    at one depth do not tell how the floor's rows change with depth."""
    min_column_spread: float = 0.1
    """Spread of the other readings' foot columns, in image widths, the floor needs (for its roll)."""
    min_confidence: float = 0.5
    """Keypoint confidence from which a foot, and a joint of the height, counts as seen."""
    judge_cut: bool = False
    """Judge tracks whose mask reaches the frame's edge in some reading too (module docstring: the frame
    cuts them, and their feet are read inside it)."""


def foot_readings(tracks: PersonTracks, min_confidence: float
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Each reading's lowest seen foot and its keypoints' height.

    Returns:
        ``rows (P, T)`` and ``columns (P, T)`` of the lowest seen foot, ``heights (P, T)`` of the seen
        keypoints (pixels), and ``seen (P, T)`` bool: valid, a foot seen and a height of at least a pixel.
    """
    kp = tracks.keypoints2d
    conf = kp[..., 2] > min_confidence
    feet = conf[..., FOOT_JOINTS]
    foot_rows = np.where(feet, kp[..., FOOT_JOINTS, 1], -np.inf)
    lowest = foot_rows.argmax(-1)[..., None]
    rows = np.take_along_axis(foot_rows, lowest, -1)[..., 0]
    columns = np.take_along_axis(kp[..., FOOT_JOINTS, 0], lowest, -1)[..., 0]
    top = np.where(conf, kp[..., 1], np.inf).min(-1)
    bottom = np.where(conf, kp[..., 1], -np.inf).max(-1)
    heights = np.where(conf.any(-1), bottom - top, 0.0)
    seen = tracks.valid & feet.any(-1) & (heights >= 1.0)
    return (np.where(seen, rows, 0.0), np.where(seen, columns, 0.0), np.where(seen, heights, 0.0), seen)


def fit_floor(rows: np.ndarray, depths: np.ndarray, columns: np.ndarray, scale: float) -> np.ndarray:
    """``(a, b, c)`` of the floor's rows ``v = a + b / Z + c u`` through readings' feet (module docstring).

    Args:
        rows, depths, columns: ``(N,)`` foot rows (px), root depths (m, positive) and foot columns (px).
        scale: residual (px) where the soft-L1 loss turns from quadratic to linear.
    """
    design = np.stack([np.ones_like(depths), 1.0 / depths, columns], axis=1)
    start = np.linalg.lstsq(design, rows, rcond=None)[0]
    result = least_squares(lambda x: design @ x - rows, start, loss="soft_l1", f_scale=scale, method="trf")
    return result.x


def cut_by_edge(masks: np.ndarray, valid: np.ndarray, width: int) -> np.ndarray:
    """``(P,)`` bool: whether a person's mask reaches the frame's edge (its first or last row or column) in
    any of their valid frames; ``masks (P, T, H, ceil(W / 8))`` with each row's pixels packed into bytes
    (``np.packbits(..., axis=-1)``, as :class:`~multithumbs.types.PersonTracks` stores them), ``valid (P, T)``."""
    rows = masks[..., [0, -1], :].any((-1, -2))
    columns = np.unpackbits(masks[..., [0, (width - 1) // 8]], axis=-1)[..., [0, 8 + (width - 1) % 8]].any((-1, -2))
    return ((rows | columns) & valid).any(-1)


def _spans_a_floor(others: np.ndarray, depths: np.ndarray, columns: np.ndarray, width: int,
                   config: FloorCheckConfig) -> bool:
    """Whether the readings ``others (P, T)`` are enough, and spread enough, to fit a floor to."""
    if others.sum() < config.min_floor_readings or others.any(1).sum() < config.min_floor_tracks:
        return False
    inverse = 1.0 / depths[others]
    spread = (inverse.max() - inverse.min()) / np.median(inverse)
    return bool(spread >= config.min_depth_spread and np.ptp(columns[others]) >= config.min_column_spread * width)


def floor_offsets(tracks: PersonTracks, config: FloorCheckConfig = FloorCheckConfig()
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Each short track's median offset of its feet from the floor the other tracks stand on, and how much
    those others scatter about it, both in keypoints' heights (module docstring).

    Returns:
        ``offsets (P,)`` (signed: positive below the floor) and ``scatters (P,)`` (1.4826 times the other
        readings' median absolute deviation from their median offset); NaN for a track not judged (long,
        no feet seen, cut by the frame's edge, the others' readings too few or too close together to fit a
        floor to).
    """
    rows, columns, heights, seen = foot_readings(tracks, config.min_confidence)
    depths = tracks.transl[..., 2]
    seen &= depths > 0
    depths, heights = np.where(seen, depths, 1.0), np.where(seen, heights, 1.0)  # no division by 0 where unseen
    offsets, scatters = np.full(tracks.num_people, np.nan), np.full(tracks.num_people, np.nan)
    cut = (np.zeros(tracks.num_people, bool) if config.judge_cut
           else cut_by_edge(tracks.masks, tracks.valid, tracks.image_size[1]))
    for p in range(tracks.num_people):
        if not seen[p].any() or tracks.valid[p].sum() > config.max_readings or cut[p]:
            continue
        others = seen.copy()
        others[p] = False
        if not _spans_a_floor(others, depths, columns, tracks.image_size[1], config):
            continue
        floor = fit_floor(rows[others], depths[others], columns[others], 0.05 * float(np.median(heights[others])))
        offset = (rows - (floor[0] + floor[1] / depths + floor[2] * columns)) / heights
        theirs = offset[others]
        offsets[p] = float(np.median(offset[p, seen[p]]))
        scatters[p] = float(1.4826 * np.median(np.abs(theirs - np.median(theirs))))
    return offsets, scatters


def keep_people(tracks: PersonTracks, keep: np.ndarray) -> PersonTracks:
    """``tracks`` with only the people where ``keep (P,)`` is true."""
    keep = np.asarray(keep, bool)
    per_person = ("track_ids", "global_orient", "body_pose", "betas", "transl", "keypoints2d", "masks",
                  "appearance", "appearance_valid", "valid")
    return dataclasses.replace(tracks, **{name: getattr(tracks, name)[keep] for name in per_person})


def drop_off_floor(tracks: PersonTracks, config: FloorCheckConfig = FloorCheckConfig()) -> PersonTracks:
    """``tracks`` without the short tracks whose feet are off the floor (module docstring)."""
    if not config.enabled or tracks.num_people < 2:
        return tracks
    offsets, scatters = floor_offsets(tracks, config)
    off = (np.abs(offsets) > config.max_offset) & (np.abs(offsets) > config.min_scatters * scatters)
    return keep_people(tracks, ~off)


__all__ = ["FloorCheckConfig", "FOOT_JOINTS", "cut_by_edge", "foot_readings", "fit_floor", "floor_offsets",
           "keep_people", "drop_off_floor"]
