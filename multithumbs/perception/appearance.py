"""Appearance of imported tracks from the video's pixels, for the re-identification term A (paper §3.4).

:func:`fill_appearance` describes every valid (track, frame) with
:func:`multithumbs.appearance.describe_person` — region hue-saturation histograms and Lab chromaticity of
the person's mask pixels, regions split by the 2D skeleton — exactly as the synthetic benchmark's
perception does, so re-ID compares like with like.

How 4DHumans' ``appe`` codes combine with it: re-ID's A (:func:`multithumbs.appearance.appearance_dissimilarity`)
compares region descriptors and cannot read PHALP's 4096-d UV-texture code, so ``PersonTracks.appearance``
is always the pixel descriptor. When the file has ``appe`` codes they VET the pixel descriptors: within a
track and shot, a frame whose code is far from the track's median code (beyond ``median + k * MAD`` of
the distances, robust scale) is an occlusion, a partial view or a mixed-up detection, and its descriptor is
marked invalid, so it does not enter the descriptors averaged next to a cut. The codes themselves are
kept in :class:`multithumbs.perception.phalp.PhalpImport` for callers that want PHALP's own cue.

Skeletons without spine, neck, collar or head joints (ViTPose's COCO joints, HMR2's OpenPose joints) are
completed for the region split only (:func:`complete_skeleton`): the stored keypoints do not change.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Iterable, Iterator, Sequence

import numpy as np

from multithumbs.appearance import DESCRIPTOR_SIZE, REGION_SIZE, describe_person
from multithumbs.errors import InputError
from multithumbs.types import PersonTracks
from multithumbs.video import iter_frames


def complete_skeleton(keypoints: np.ndarray, min_confidence: float = 0.3) -> np.ndarray:
    """Fill missing torso and head joints of SMPL-order keypoints ``(..., 24, 3)`` from the others.

    Pelvis: mid-hip; neck: mid-shoulder; spine1/2/3: a quarter, half and three quarters from pelvis to
    neck; collars: halfway from neck to shoulder; head: 0.4 of the pelvis-to-neck length above the neck
    (SMPL's proportions). A filled joint's confidence is the smallest of its sources'. Joints already
    above ``min_confidence`` are kept.
    """
    kp = np.array(keypoints, dtype=np.float64, copy=True)

    def fill(target: int, point: np.ndarray, conf: np.ndarray) -> None:
        missing = kp[..., target, 2] < min_confidence
        usable = missing & (conf >= min_confidence)
        kp[..., target, :2] = np.where(usable[..., None], point, kp[..., target, :2])
        kp[..., target, 2] = np.where(usable, conf, kp[..., target, 2])

    def mid(a: int, b: int, t: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
        return (1 - t) * kp[..., a, :2] + t * kp[..., b, :2], np.minimum(kp[..., a, 2], kp[..., b, 2])

    fill(0, *mid(1, 2))
    fill(12, *mid(16, 17))
    for joint, t in ((3, 0.25), (6, 0.5), (9, 0.75)):
        fill(joint, *mid(0, 12, t))
    fill(13, *mid(12, 16))
    fill(14, *mid(12, 17))
    fill(15, *mid(0, 12, 1.4))
    return kp


def _frames(video: str | Path | np.ndarray, start: int, stop: int) -> Iterator[np.ndarray]:
    if isinstance(video, np.ndarray):
        yield from video[start:stop]
    else:
        yield from iter_frames(video, start, stop)


def uv_outliers(codes: np.ndarray, valid: np.ndarray, k: float = 3.0, min_frames: int = 3) -> np.ndarray:
    """``(P, T)`` bool: frames whose UV code is far from its track's median code (module docstring).

    Args:
        codes: ``(P, T, D)`` PHALP ``appe`` codes.
        valid: ``(P, T)`` bool, a code exists.
        k: threshold in robust standard deviations (1.4826 MAD) above the median distance.
        min_frames: tracks with fewer codes are not vetted.
    """
    out = np.zeros(valid.shape, bool)
    for i in range(valid.shape[0]):
        rows = np.nonzero(valid[i])[0]
        if rows.size < min_frames:
            continue
        centre = np.median(codes[i, rows], axis=0)
        dist = np.linalg.norm(codes[i, rows] - centre, axis=-1)
        med = np.median(dist)
        spread = 1.4826 * np.median(np.abs(dist - med))
        out[i, rows] = dist > med + k * max(spread, 1e-6 * max(med, 1e-12))
    return out


def fill_appearance(tracks: Sequence[PersonTracks], video: str | Path | np.ndarray,
                    uv_appearance: Sequence[np.ndarray | None] | None = None,
                    uv_valid: Sequence[np.ndarray | None] | None = None, uv_outlier_k: float = 3.0,
                    progress=None) -> list[PersonTracks]:
    """Per-shot tracks with ``appearance`` described from the video's pixels (module docstring).

    Args:
        tracks: one :class:`PersonTracks` per shot, with masks and SMPL-order keypoints.
        video: the video file, or its frames ``(T, H, W, 3)`` uint8 RGB.
        uv_appearance: per shot ``(P, T, D)`` PHALP ``appe`` codes (or None) that vet the descriptors.
        uv_valid: per shot ``(P, T)`` bool with ``uv_appearance``.
        uv_outlier_k: :func:`uv_outliers` threshold.
        progress: optional ``callable(done_frames, total_frames)``.
    Returns:
        new tracks; ``appearance (P, T, DESCRIPTOR_SIZE)`` and ``appearance_valid`` replaced.
    Raises:
        InputError: the video ends before the tracks do, or its frames are not the tracks' image size.
    """
    total = sum(tr.num_frames for tr in tracks)
    out, done = [], 0
    for k, tr in enumerate(tracks):
        p, t = tr.valid.shape
        h, w = tr.image_size
        desc = np.zeros((p, t, DESCRIPTOR_SIZE))
        ok = np.zeros((p, t), bool)
        keypoints = complete_skeleton(tr.keypoints2d) if tr.keypoints2d.shape[2] == 24 else tr.keypoints2d
        seen = 0
        for j, frame in enumerate(_frames(video, tr.start_frame, tr.start_frame + t)):
            seen = j + 1
            if frame.shape[:2] != (h, w):
                raise InputError(f"{_name(video)}: frame {tr.start_frame + j} is {frame.shape[0]}x{frame.shape[1]}, "
                                 f"the tracks are for {h}x{w}")
            for i in np.nonzero(tr.valid[:, j])[0]:
                desc[i, j] = describe_person(frame, tr.mask(int(i), j), keypoints[i, j])
                ok[i, j] = desc[i, j, ::REGION_SIZE].any()
            if progress:
                progress(done + seen, total)
        if seen < t:
            raise InputError(f"{_name(video)}: the video ends at frame {tr.start_frame + seen} but shot {k}'s "
                             f"tracks run to frame {tr.start_frame + t - 1}")
        done += t
        if uv_appearance is not None and uv_appearance[k] is not None:
            vet = uv_valid[k] if uv_valid is not None and uv_valid[k] is not None else tr.valid
            ok &= ~uv_outliers(np.asarray(uv_appearance[k]), vet & tr.valid, uv_outlier_k)
        out.append(dataclasses.replace(tr, appearance=desc, appearance_valid=ok))
    return out


def _name(video: str | Path | Iterable) -> str:
    return str(video) if isinstance(video, (str, Path)) else "frames"
