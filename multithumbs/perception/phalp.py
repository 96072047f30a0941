"""4DHumans / PHALP tracking results: import into per-shot :class:`PersonTracks`, and export.

PHALP's ``track.py`` (which 4DHumans runs with HMR2 inside) writes ``results/<video>.pkl`` with
``joblib.dump`` (``phalp/trackers/PHALP.py:264``): a dict keyed by frame name
(``outputs//_DEMO/<video>/img/000001.jpg``: PHALP's frame extractor numbers frames FROM 1,
``phalp/utils/utils.py:176``), or by ``(video_path, pts)`` with ``video.extract_video=False``. Each frame
holds ``time`` (the 0-based index, by which frames are placed), ``shot`` (1 on a frame where PHALP's own
PySceneDetect found a cut, only with ``detect_shots=True``), ``frame_path`` and lists over the CONFIRMED
tracks of that frame, including tracks lost for up to 50 frames (ghosts with their last detection's stale
values):

* ``tid``: track id; ``tracked_ids``: the ids actually detected in this frame (the others are PHALP's
  predictions for tracks it lost for a few frames, not observations; ``tracked_time`` says the same);
* ``smpl``: ``{"global_orient": (1, 3, 3), "body_pose": (23, 3, 3), "betas": (10,)}`` rotation matrices;
* ``camera``: ``(3,)`` camera-frame translation of the SMPL body (HMR2's camera, :mod:`.camera`);
* ``bbox``: ``(4,)`` ``x, y, w, h`` pixels; ``mask``: COCO run-length encodings (``pycocotools``);
* ``2d_joints``: ``(90,)`` HMR2's 45 joints PROJECTED through HMR2's own camera (focal 5000 on the padded
  256-px square) and divided by 256 (``phalp/models/hmar/hmar.py:119-131``, ``PHALP.py:430``): the
  mesh's joints, not what a keypoint detector saw;
* ``appe``: ``(4096,)`` PHALP's appearance code of the UV texture map; ``size``: ``[H, W]``; and more
  (``center``, ``scale``, ``conf``, ``3d_joints``, ``loca``, ``pose``...) that the import does not need.

The import splits the video by OUR detected cuts (a :class:`Shots`), not PHALP's ``shot`` flags (those are
reported for comparison): a PHALP track that runs through a cut becomes one track in each shot, with the
same local id. Track ids are PHALP's ``tid``. ``betas`` are averaged over a track's frames in a shot
(HMR2 predicts them per frame; the contract keeps one shape per track). ``keypoints2d`` are the SMPL
joints that HMR2's OpenPose joints are (:mod:`.joints`), confidence 1 inside the image and 0 elsewhere, as
HMR2's camera projects them; they carry no evidence beyond the 3D, so :func:`multithumbs.perception.load_perception`
reprojects them through the camera the method will use (:mod:`.model_keypoints`), and ViTPose can replace
them with detected keypoints (:mod:`.transformers_backends`). Appearance is left empty here and filled from
pixels by :func:`multithumbs.perception.appearance.fill_appearance`.

Loading a pickle runs code from the file: :func:`read_phalp_results` refuses unless ``trust=True``.
"""

from __future__ import annotations

import os
import re
import tempfile
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

import numpy as np
from scipy.spatial.transform import Rotation

from multithumbs.appearance import DESCRIPTOR_SIZE
from multithumbs.errors import InputError
from multithumbs.geometry import reexpress_for_intrinsics
from multithumbs.io import publish
from multithumbs.perception.camera import (
    HMR2_CROP_SIZE,
    HMR2_FOCAL_LENGTH,
    hmr2_intrinsics,
    phalp_joints_to_pixels,
    pixels_to_phalp_joints,
)
from multithumbs.perception.joints import (
    OPENPOSE25_TO_SMPL24,
    PHALP_NUM_JOINTS,
    openpose25_to_smpl24,
    smpl24_to_openpose,
)
from multithumbs.types import PersonTracks, Shots, pack_mask

REQUIRED_FIELDS = ("smpl", "camera", "bbox")
"""Per-detection fields without which a track cannot be imported."""

_SMPL_FROM_OPENPOSE = np.isin(np.arange(24), list(OPENPOSE25_TO_SMPL24.values()))
_OPENPOSE_FROM_SMPL = np.isin(np.arange(PHALP_NUM_JOINTS), list(OPENPOSE25_TO_SMPL24))


@dataclass(frozen=True)
class PhalpImport:
    """Tracks of a PHALP results file, split into the shots of a :class:`Shots`.

    Attributes:
        tracks: one :class:`PersonTracks` per shot (appearance empty until filled from pixels).
        boxes: per shot ``(P, T, 4)`` boxes ``x0, y0, x1, y1`` in pixels, pixel centres at integers as in
            :mod:`multithumbs.conventions` (PHALP's continuous ``bbox`` shifted by -0.5); 0 where not valid.
        uv_appearance: per shot ``(P, T, D)`` PHALP ``appe`` codes, or ``None`` when the file has none.
        uv_valid: per shot ``(P, T)`` bool, an ``appe`` code was read; ``None`` with ``uv_appearance``.
        phalp_cut_frames: ``(C',)`` frames PHALP itself flagged as the first of a new shot.
        source: the file the tracks came from.
    """

    tracks: tuple[PersonTracks, ...]
    boxes: tuple[np.ndarray, ...]
    uv_appearance: tuple[np.ndarray, ...] | None
    uv_valid: tuple[np.ndarray, ...] | None
    phalp_cut_frames: np.ndarray
    source: str


def read_phalp_results(path: str | Path, trust: bool = False) -> dict:
    """Load a PHALP/4DHumans ``.pkl`` (joblib) after the caller has said it trusts the file.

    Raises:
        InputError: without ``trust``, for a missing or unreadable file, or one whose top level is not a
            dict keyed by frame name.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: no such results file")
    if not trust:
        raise InputError(f"{path}: loading a pickle runs code stored in it; pass trust=True (--trust) only "
                         f"for results files you made or trust")
    import joblib

    try:
        results = joblib.load(path)
    except Exception as exc:
        raise InputError(f"{path}: not a readable joblib/pickle file ({exc.__class__.__name__}: "
                         f"{str(exc).splitlines()[0][:120] if str(exc) else ''})") from None
    if not isinstance(results, dict) or not results:
        kind = type(results).__name__ if not isinstance(results, dict) else "an empty dict"
        raise InputError(f"{path}: not a 4DHumans/PHALP results file (top level is {kind}, expected a dict "
                         f"keyed by frame name)")
    return results


_TRAILING_NUMBER = re.compile(r"(\d+)(?!.*\d)")
_DEMO_VIDEO = re.compile(r"_DEMO/([^/]+)/img/")


def frame_index(name: Any, first: int = 1) -> int:
    """0-based video frame of a PHALP frame name: its last number minus ``first``.

    PHALP's frame extractor names frames ``'%06d' % (img_cnt + 1)`` (``phalp/utils/utils.py:176``), so the
    first frame is ``000001.jpg`` and ``first`` defaults to 1. A ``(video, pts)`` tuple key (PHALP's
    ``extract_video=False``, ``phalp/utils/io.py:81``) holds a stream timestamp, not an index: it has no
    frame index, and :class:`InputError` says so (:func:`import_phalp` places such frames by ``time``).
    """
    if isinstance(name, tuple):
        raise InputError(f"frame {name!r}: a (video, pts) key holds a stream timestamp, not a frame index, and "
                         f"the frame has no 'time' field to place it")
    if not isinstance(name, (str, os.PathLike)):
        raise InputError(f"frame {name!r}: a frame name must be a file name with the frame number")
    stem = Path(name).stem
    match = _TRAILING_NUMBER.search(stem)
    if match is None:
        raise InputError(f"frame {str(name)!r}: the name has no frame number, so it cannot be matched to "
                         f"the video's frames")
    return int(match.group(1)) - first


def _frame_time(name: Any, frame: dict, label: str, first: int) -> int:
    """The frame's 0-based index: its ``time`` (``PHALP.py:208``), checked against the number in its name.

    ``time`` is PHALP's loop counter over the frames it processed. It is the video frame only when PHALP
    started at the video's first frame (``video.start_frame = -1``, the default); then the name says the
    same, counted from 1. When the two disagree the run started elsewhere and neither can be trusted to place
    the frame, so the import refuses rather than shift every frame.
    """
    number = None if isinstance(name, tuple) else frame_index(name, first)
    if "time" not in frame:
        return frame_index(name, first)
    try:
        time = int(np.asarray(frame["time"]).reshape(-1)[0])
    except (TypeError, ValueError, IndexError):
        raise InputError(f"frame {label!r}: field 'time' is not a frame index") from None
    if number is not None and number != time:
        raise InputError(f"frame {label!r}: the name numbers it video frame {number} (counted from {first}) but its "
                         f"'time' is {time}; was PHALP run from another start_frame?")
    return time


def results_video_name(results: dict) -> str | None:
    """The video a results file was made from, as its keys name it (``_DEMO/<video>/img/``, or the file
    name of a ``(video, pts)`` key), or ``None`` when the keys do not say."""
    names = set()
    for key in results:
        if isinstance(key, tuple) and key and isinstance(key[0], (str, os.PathLike)):
            names.add(Path(key[0]).stem)
        elif isinstance(key, str) and (match := _DEMO_VIDEO.search(key)):
            names.add(match.group(1))
    return names.pop() if len(names) == 1 else None


def _field(frame: dict, key: str, name: str, count: int) -> list | None:
    if key not in frame:
        return None
    values = frame[key]
    if not isinstance(values, (list, tuple)) or len(values) != count:
        got = len(values) if isinstance(values, (list, tuple)) else type(values).__name__
        raise InputError(f"frame {name!r}: field {key!r} has {got} entries for {count} tracks")
    return list(values)


def _rotations(value: Any, joints: int, where: str) -> np.ndarray:
    """``(joints, 3)`` axis-angle from rotation matrices ``(joints, 3, 3)`` (or axis-angle ``(joints, 3)``)."""
    arr = np.asarray(value, dtype=np.float64)
    if arr.size == joints * 9:
        mats = arr.reshape(joints, 3, 3)
        if not np.allclose(np.einsum("nij,nkj->nik", mats, mats), np.eye(3), atol=1e-3):
            raise InputError(f"{where}: not rotation matrices")
        return Rotation.from_matrix(mats).as_rotvec()
    if arr.size == joints * 3:
        return arr.reshape(joints, 3)
    raise InputError(f"{where}: expected ({joints}, 3, 3) rotation matrices, got shape {arr.shape}")


def _decode_mask(value: Any, image_size: tuple[int, int], where: str) -> np.ndarray:
    from pycocotools import mask as mask_utils

    rle = value[0] if isinstance(value, (list, tuple)) and len(value) == 1 else value
    if not isinstance(rle, dict) or "counts" not in rle or "size" not in rle:
        raise InputError(f"{where}: mask is not a COCO run-length encoding (dict with 'size' and 'counts')")
    if tuple(int(s) for s in rle["size"]) != tuple(image_size):
        raise InputError(f"{where}: mask size {list(rle['size'])} does not match the video "
                         f"({image_size[0]}x{image_size[1]})")
    counts = rle["counts"]
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecationWarning)  # pycocotools' numpy-2 copy= notice
            mask = mask_utils.decode({"size": [int(s) for s in rle["size"]],
                                      "counts": counts.encode() if isinstance(counts, str) else counts})
    except Exception as exc:
        raise InputError(f"{where}: corrupt run-length mask ({exc.__class__.__name__})") from None
    return mask.reshape(image_size).astype(bool)


def _observed(frame: dict, tids: list, name: str) -> list[bool]:
    """Which entries are detections in this frame (not PHALP's predictions for a lost track)."""
    if "tracked_ids" in frame:
        tracked = {int(t) for t in frame["tracked_ids"]}
        return [int(t) in tracked for t in tids]
    times = _field(frame, "tracked_time", name, len(tids))
    if times is not None:
        return [int(t) == 0 for t in times]
    return [True] * len(tids)


def import_phalp(results: dict, shots: Shots, image_size: tuple[int, int], source: str = "results",
                 first_frame_number: int = 1, focal_length: float = HMR2_FOCAL_LENGTH,
                 crop_size: int = HMR2_CROP_SIZE, video_name: str | None = None) -> PhalpImport:
    """Split PHALP results into per-shot tracks (module docstring: what is read and how).

    Args:
        results: the loaded results dict (:func:`read_phalp_results`).
        shots: the video's shots (our cut detection).
        image_size: ``(H, W)`` of the video.
        source: name of the results for messages.
        first_frame_number: the number in the name of the video's first frame, for frames without ``time``
            (PHALP's extractor counts from 1).
        video_name: the video's name (file stem); a file whose keys name another video is refused.
        focal_length: HMR2's crop focal length (``EXTRA.FOCAL_LENGTH``).
        crop_size: HMR2's crop size (PHALP's ``render.res``).
    Raises:
        InputError: one line naming the frame and field for: a pickle of another tool, missing or
            malformed fields, frame names without frame numbers, a name and ``time`` that disagree, frames
            beyond the video's end (a longer or another video), keys naming another video, detections whose
            image size differs from the video's.

    Frames are placed by their ``time``. A file with FEWER frames than the video (PHALP stops before
    ``video.end_frame``, 1300 by default, ``phalp/configs/base.py:17``) is loaded aligned by ``time``: the
    frames it lacks simply have no detections. Nothing is shifted to make the counts agree.
    """
    named = results_video_name(results)
    if video_name is not None and named is not None and named != video_name:
        raise InputError(f"{source}: the results are of video {named!r} (frame keys _DEMO/{named}/img/...), not "
                         f"of {video_name!r}")
    h, w = (int(s) for s in image_size)
    frames: dict[int, tuple[str, dict]] = {}
    for name, frame in results.items():
        label = str(name) if not isinstance(name, tuple) else f"{name[0]}@pts={name[-1]}"
        if not isinstance(frame, dict) or "tid" not in frame:
            raise InputError(f"{source}: not a 4DHumans/PHALP results file (frame {label!r} has no 'tid' "
                             f"field; a pickle from a different tool?)")
        try:
            index = _frame_time(name, frame, label, first_frame_number)
        except InputError as exc:
            raise InputError(f"{source}: {exc}") from None
        if index < 0:
            raise InputError(f"{source}: frame {label!r} has index {index} before the video's first frame")
        if index >= shots.num_frames:
            raise InputError(f"{source}: frame {label!r} (index {index}) is beyond the end of the video "
                             f"({shots.num_frames} frames): results of a longer or another video")
        if index in frames:
            raise InputError(f"{source}: frames {frames[index][0]!r} and {label!r} both name frame {index}")
        frames[index] = (label, frame)

    # Per frame: tid -> parsed detection.
    parsed: dict[int, dict[int, dict]] = {}
    phalp_cuts = []
    for index in sorted(frames):
        label, frame = frames[index]
        flag = np.asarray(frame.get("shot", 0)).reshape(-1)
        if index > 0 and flag.size and flag[0]:
            phalp_cuts.append(index)
        tids = list(frame["tid"]) if isinstance(frame["tid"], (list, tuple, np.ndarray)) else None
        if tids is None:
            raise InputError(f"{source}: frame {label!r}: field 'tid' is not a list")
        observed = _observed(frame, tids, label)
        fields = {key: _field(frame, key, label, len(tids)) for key in
                  ("smpl", "camera", "bbox", "mask", "2d_joints", "appe", "size")}
        detections: dict[int, dict] = {}
        for k, tid in enumerate(tids):
            if not observed[k]:
                continue
            where = f"{source}: frame {label!r}, track {int(tid)}"
            for key in REQUIRED_FIELDS:
                if fields[key] is None:
                    raise InputError(f"{source}: frame {label!r}: missing field {key!r}")
            if int(tid) in detections:
                raise InputError(f"{where}: the track id appears twice in one frame")
            if fields["size"] is not None:
                size = tuple(int(s) for s in np.asarray(fields["size"][k]).reshape(-1)[:2])
                if size != (h, w):
                    raise InputError(f"{where}: detection image size {size[0]}x{size[1]} does not match the "
                                     f"video ({h}x{w})")
            smpl = fields["smpl"][k]
            if not isinstance(smpl, dict):
                raise InputError(f"{where}: field 'smpl' is not a dict of SMPL parameters")
            for key in ("global_orient", "body_pose", "betas"):
                if key not in smpl:
                    raise InputError(f"{where}: missing field 'smpl.{key}'")
            det = {
                "global_orient": _rotations(smpl["global_orient"], 1, f"{where}: smpl.global_orient")[0],
                "body_pose": _rotations(smpl["body_pose"], 23, f"{where}: smpl.body_pose"),
                "betas": np.asarray(smpl["betas"], dtype=np.float64).reshape(-1),
                "transl": np.asarray(fields["camera"][k], dtype=np.float64).reshape(-1),
                "bbox": np.asarray(fields["bbox"][k], dtype=np.float64).reshape(-1),
            }
            if det["betas"].size < 10:
                raise InputError(f"{where}: smpl.betas has {det['betas'].size} values, expected 10")
            det["betas"] = det["betas"][:10]
            for key, size in (("transl", 3), ("bbox", 4)):
                if det[key].size != size:
                    name = "camera" if key == "transl" else key
                    raise InputError(f"{where}: field {name!r} has {det[key].size} values, expected {size}")
            for key in ("global_orient", "body_pose", "betas", "transl", "bbox"):
                if not np.all(np.isfinite(det[key])):
                    raise InputError(f"{where}: field {key!r} has non-finite values")
            if fields["mask"] is not None and fields["mask"][k] is not None:
                det["mask"] = _decode_mask(fields["mask"][k], (h, w), where)
            if fields["2d_joints"] is not None:
                joints = np.asarray(fields["2d_joints"][k], dtype=np.float64).reshape(-1)
                if joints.size < 50 or joints.size % 2:
                    raise InputError(f"{where}: field '2d_joints' has {joints.size} values, expected "
                                     f"{2 * PHALP_NUM_JOINTS} (HMR2's joints, x and y)")
                det["joints2d"] = phalp_joints_to_pixels(joints, (h, w))
            if fields["appe"] is not None and fields["appe"][k] is not None:
                det["appe"] = np.asarray(fields["appe"][k], dtype=np.float64).reshape(-1)
            detections[int(tid)] = det
        parsed[index] = detections

    K = hmr2_intrinsics((h, w), focal_length, crop_size)
    has_appe = any("appe" in d for dets in parsed.values() for d in dets.values())
    appe_dim = max((d["appe"].size for dets in parsed.values() for d in dets.values() if "appe" in d), default=0)
    tracks, boxes, uv, uv_valid = [], [], [], []
    for shot, (a, b) in enumerate(shots.ranges):
        ids = sorted({tid for f in range(a, b) for tid in parsed.get(f, {})})
        p, t = len(ids), b - a
        row = {tid: i for i, tid in enumerate(ids)}
        orient, pose = np.zeros((p, t, 3)), np.zeros((p, t, 23, 3))
        transl, keypoints = np.zeros((p, t, 3)), np.zeros((p, t, 24, 3))
        betas_sum, valid = np.zeros((p, 10)), np.zeros((p, t), bool)
        masks = np.zeros((p, t, h, (w + 7) // 8), np.uint8)
        box = np.zeros((p, t, 4))
        appe = np.zeros((p, t, appe_dim)) if has_appe else None
        appe_ok = np.zeros((p, t), bool)
        for f in range(a, b):
            for tid, det in parsed.get(f, {}).items():
                i, j = row[tid], f - a
                valid[i, j] = True
                orient[i, j], pose[i, j], transl[i, j] = det["global_orient"], det["body_pose"], det["transl"]
                betas_sum[i] += det["betas"]
                x, y, bw, bh = det["bbox"] - np.array([0.5, 0.5, 0.0, 0.0])  # to integer pixel centres
                box[i, j] = (x, y, x + bw, y + bh)
                if "mask" in det:
                    masks[i, j] = pack_mask(det["mask"])
                if "joints2d" in det:
                    uv_px = openpose25_to_smpl24(det["joints2d"])
                    inside = ((uv_px[:, 0] >= -0.5) & (uv_px[:, 0] < w - 0.5) & (uv_px[:, 1] >= -0.5)
                              & (uv_px[:, 1] < h - 0.5))
                    keypoints[i, j, :, :2] = np.where(_SMPL_FROM_OPENPOSE[:, None], uv_px, 0.0)
                    keypoints[i, j, :, 2] = (_SMPL_FROM_OPENPOSE & inside).astype(float)
                if appe is not None and "appe" in det and det["appe"].size == appe_dim:
                    appe[i, j], appe_ok[i, j] = det["appe"], True
        betas = betas_sum / np.maximum(valid.sum(1), 1)[:, None]
        tracks.append(PersonTracks(
            shot_index=shot, start_frame=a, track_ids=np.asarray(ids, dtype=np.int64).reshape(p),
            global_orient=orient, body_pose=pose, betas=betas.reshape(p, 10), transl=transl,
            keypoints2d=keypoints, masks=masks, image_size=(h, w), K=K,
            appearance=np.zeros((p, t, DESCRIPTOR_SIZE)), appearance_valid=np.zeros((p, t), bool), valid=valid))
        boxes.append(box)
        uv.append(appe)
        uv_valid.append(appe_ok)
    return PhalpImport(tuple(tracks), tuple(boxes), tuple(uv) if has_appe else None,
                       tuple(uv_valid) if has_appe else None, np.asarray(phalp_cuts, dtype=np.int64), source)


def load_phalp(path: str | Path, shots: Shots, image_size: tuple[int, int], trust: bool = False,
               first_frame_number: int = 1, video_name: str | None = None) -> PhalpImport:
    """:func:`read_phalp_results` then :func:`import_phalp`."""
    return import_phalp(read_phalp_results(path, trust), shots, image_size, source=str(path),
                        first_frame_number=first_frame_number, video_name=video_name)
