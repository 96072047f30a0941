"""4DHumans / PHALP tracking results: import into per-shot :class:`PersonTracks`, and export.

PHALP's ``track.py`` (which 4DHumans runs with HMR2 inside) writes ``results/<video>.pkl`` with
``joblib.dump``: a dict keyed by frame name (``_DEMO/<video>/img/000000.jpg``, frames numbered from 0 by
PHALP's frame extractor). Each frame holds ``time``, ``shot`` (1 on a frame where PHALP's own PySceneDetect
found a cut, else 0), ``frame_path`` and lists over the confirmed tracks of that frame:

* ``tid``: track id; ``tracked_ids``: the ids actually detected in this frame (the others are PHALP's
  predictions for tracks it lost for a few frames, not observations; ``tracked_time`` says the same);
* ``smpl``: ``{"global_orient": (1, 3, 3), "body_pose": (23, 3, 3), "betas": (10,)}`` rotation matrices;
* ``camera``: ``(3,)`` camera-frame translation of the SMPL body (HMR2's camera, :mod:`.camera`);
* ``bbox``: ``(4,)`` ``x, y, w, h`` pixels; ``mask``: COCO run-length encodings (``pycocotools``);
* ``2d_joints``: ``(90,)`` HMR2's 45 projected joints normalised to the zero-padded square frame;
* ``appe``: ``(4096,)`` PHALP's appearance code of the UV texture map; ``size``: ``[H, W]``; and more
  (``center``, ``scale``, ``conf``, ``3d_joints``, ``loca``, ``pose``...) that the import does not need.

The import splits the video by OUR detected cuts (a :class:`Shots`), not PHALP's ``shot`` flags (those are
reported for comparison): a PHALP track that runs through a cut becomes one track in each shot, with the
same local id. Track ids are PHALP's ``tid``. ``betas`` are averaged over a track's frames in a shot
(HMR2 predicts them per frame; the contract keeps one shape per track). ``keypoints2d`` are the SMPL
joints that HMR2's OpenPose joints are (:mod:`.joints`), confidence 1 inside the image and 0 elsewhere;
ViTPose can replace them (:mod:`.transformers_backends`). Appearance is left empty here and filled from
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


def frame_index(name: Any, offset: int = 0) -> int:
    """Video frame index of a PHALP frame key: the last number in the file name, or the index of a
    ``(video, index)`` tuple key, minus ``offset`` (PHALP numbers extracted frames from 0)."""
    if isinstance(name, tuple) and len(name) == 2 and isinstance(name[1], (int, np.integer)):
        return int(name[1]) - offset
    if not isinstance(name, (str, os.PathLike)):
        raise InputError(f"frame {name!r}: a frame name must be a file name with the frame number")
    stem = Path(name).stem
    match = _TRAILING_NUMBER.search(stem)
    if match is None:
        raise InputError(f"frame {str(name)!r}: the name has no frame number, so it cannot be matched to "
                         f"the video's frames")
    return int(match.group(1)) - offset


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
                 frame_offset: int = 0, focal_length: float = HMR2_FOCAL_LENGTH,
                 crop_size: int = HMR2_CROP_SIZE) -> PhalpImport:
    """Split PHALP results into per-shot tracks (module docstring: what is read and how).

    Args:
        results: the loaded results dict (:func:`read_phalp_results`).
        shots: the video's shots (our cut detection).
        image_size: ``(H, W)`` of the video.
        source: name of the results for messages.
        frame_offset: subtracted from the frame numbers of the keys (1 for frames numbered from 1).
        focal_length: HMR2's crop focal length (``EXTRA.FOCAL_LENGTH``).
        crop_size: HMR2's crop size (PHALP's ``render.res``).
    Raises:
        InputError: one line naming the frame and field for: a pickle of another tool, missing or
            malformed fields, frame names without frame numbers, frames beyond the video's end,
            detections whose image size differs from the video's.
    """
    h, w = (int(s) for s in image_size)
    frames: dict[int, tuple[str, dict]] = {}
    for name, frame in results.items():
        label = str(name if not isinstance(name, tuple) else name[0])
        if not isinstance(frame, dict) or "tid" not in frame:
            raise InputError(f"{source}: not a 4DHumans/PHALP results file (frame {label!r} has no 'tid' "
                             f"field; a pickle from a different tool?)")
        try:
            index = frame_index(name, frame_offset)
        except InputError as exc:
            raise InputError(f"{source}: {exc}") from None
        if index < 0:
            raise InputError(f"{source}: frame {label!r} has index {index} before the video's first frame")
        if index >= shots.num_frames:
            raise InputError(f"{source}: frame {label!r} (index {index}) is beyond the end of the video "
                             f"({shots.num_frames} frames)")
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
               frame_offset: int = 0) -> PhalpImport:
    """:func:`read_phalp_results` then :func:`import_phalp`."""
    return import_phalp(read_phalp_results(path, trust), shots, image_size, source=str(path),
                        frame_offset=frame_offset)


def mask_box(mask: np.ndarray) -> np.ndarray:
    """``(4,)`` ``x0, y0, x1, y1`` box of a boolean ``(H, W)`` mask (pixel edges), zeros when empty."""
    ys, xs = np.nonzero(mask)
    if xs.size == 0:
        return np.zeros(4)
    return np.array([xs.min() - 0.5, ys.min() - 0.5, xs.max() + 0.5, ys.max() + 0.5])


def export_phalp(path: str | Path, tracks: Sequence[PersonTracks], shots: Shots,
                 boxes: Sequence[np.ndarray] | None = None, uv_appearance: Sequence[np.ndarray] | None = None,
                 video_name: str = "video", overwrite: bool = False,
                 rest_pelvis: Sequence[np.ndarray] | None = None) -> Path:
    """Write per-shot tracks as a PHALP results file (the structure :func:`import_phalp` reads).

    Every video frame gets a key ``_DEMO/<video_name>/img/<frame:06d>.jpg``; ``shot`` flags the first frame
    of each of ``shots``' shots after the first; track ids become ``tid`` (so ids shared across shots stay
    one PHALP track); boxes default to the mask's bounding box. Fields PHALP computes from its own networks
    that cannot be derived from tracks (``3d_joints``, ``pose``, ``loca``, ``uv``, ``camera_bbox``) are not
    written; ``appe`` only when ``uv_appearance`` is given. ``2d_joints`` carries the SMPL joints HMR2's
    OpenPose joints are and zeros for the others. Arrays are float32, as PHALP stores them. Atomic write;
    an existing file is replaced only with ``overwrite``.

    ``camera`` is each track's translation re-expressed for HMR2's camera (:func:`hmr2_intrinsics`, the
    camera :func:`import_phalp` gives back), as 4DHumans reports it: the same pixel, the depth scaled by the
    focal-length ratio (:func:`multithumbs.geometry.reexpress_for_intrinsics`). The point converted is the
    pelvis when ``rest_pelvis`` gives each shot's ``(P, 3)`` rest pelvis (SMPL joint 0 of each track's
    betas; the method converts the same point back), else the SMPL origin.
    """
    import joblib
    from pycocotools import mask as mask_utils

    path = Path(path)
    if path.exists() and not overwrite:
        raise InputError(f"{path}: already exists (pass overwrite=True / --overwrite to replace it)")
    if not path.parent.is_dir():
        raise InputError(f"{path.parent}: output folder does not exist")
    if len(tracks) != shots.num_shots:
        raise InputError(f"tracks: {len(tracks)} track sets for {shots.num_shots} shots")
    h, w = tracks[0].image_size if tracks else (0, 0)
    cuts = set(shots.cut_frames.tolist())
    results: dict[str, dict] = {}
    for f in range(shots.num_frames):
        key = f"_DEMO/{video_name}/img/{f:06d}.jpg"
        results[key] = {"time": f, "shot": int(f in cuts), "frame_path": key,
                        **{k: [] for k in ("tid", "bbox", "tracked_time", "tracked_ids", "tracked_bbox", "center",
                                           "scale", "size", "img_path", "img_name", "class_name", "conf",
                                           "annotations", "smpl", "camera", "2d_joints", "mask")}}
        if uv_appearance is not None:
            results[key]["appe"] = []
    for k, ((a, b), tr) in enumerate(zip(shots.ranges, tracks)):
        if tr.num_frames != b - a or tr.start_frame != a:
            raise InputError(f"shot {k}: tracks cover frames {tr.start_frame}..{tr.start_frame + tr.num_frames - 1}"
                             f", the shot is {a}..{b - 1}")
        rest = np.zeros((tr.num_people, 1, 3)) if rest_pelvis is None else np.asarray(rest_pelvis[k])[:, None]
        camera = reexpress_for_intrinsics(tr.transl + rest, tr.K, hmr2_intrinsics(tr.image_size)) - rest
        orient = Rotation.from_rotvec(tr.global_orient.reshape(-1, 3)).as_matrix().reshape(*tr.valid.shape, 1, 3, 3)
        pose = Rotation.from_rotvec(tr.body_pose.reshape(-1, 3)).as_matrix().reshape(*tr.valid.shape, 23, 3, 3)
        for i, j in zip(*np.nonzero(tr.valid)):
            f = a + int(j)
            key = f"_DEMO/{video_name}/img/{f:06d}.jpg"
            frame = results[key]
            mask = tr.mask(int(i), int(j))
            x0, y0, x1, y1 = boxes[k][i, j] if boxes is not None else mask_box(mask)
            bbox = np.array([x0 + 0.5, y0 + 0.5, x1 - x0, y1 - y0], np.float32)  # PHALP: continuous pixels
            rles = mask_utils.encode(np.asfortranarray(mask[:, :, None].astype(np.uint8)))
            for rle in rles:
                rle["counts"] = rle["counts"].decode("utf-8")
            joints = smpl24_to_openpose(tr.keypoints2d[i, j, :24, :2]) if tr.keypoints2d.shape[2] == 24 else \
                np.zeros((PHALP_NUM_JOINTS, 2))
            flat = np.where(np.repeat(_OPENPOSE_FROM_SMPL, 2), pixels_to_phalp_joints(joints, (h, w)), 0.0)
            tid = int(tr.track_ids[i])
            frame["tid"].append(tid)
            frame["tracked_ids"].append(tid)
            frame["tracked_time"].append(0)
            frame["bbox"].append(bbox)
            frame["tracked_bbox"].append(bbox)
            frame["center"].append(np.array([(x0 + x1) / 2 + 0.5, (y0 + y1) / 2 + 0.5], np.float32))
            frame["scale"].append(np.array([x1 - x0, y1 - y0], np.float32))
            frame["size"].append([h, w])
            frame["img_path"].append(key)
            frame["img_name"].append(Path(key).name)
            frame["class_name"].append(0)
            frame["conf"].append(1.0)
            frame["annotations"].append([])
            frame["smpl"].append({"global_orient": orient[i, j].astype(np.float32),
                                  "body_pose": pose[i, j].astype(np.float32),
                                  "betas": tr.betas[i].astype(np.float32)})
            frame["camera"].append(camera[i, j].astype(np.float32))
            frame["2d_joints"].append(flat.astype(np.float32))
            frame["mask"].append(rles)
            if uv_appearance is not None:
                frame["appe"].append(np.asarray(uv_appearance[k][i, j], np.float32))
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    try:
        joblib.dump(results, tmp, compress=3)
        publish(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path
