"""A PHALP results file assembled by hand from upstream's code paths (not by this project's exporter).

Line references are to brjathu/PHALP at 96f7e6c (``phalp/trackers/PHALP.py`` unless named otherwise).
The video: 4 frames of 64x48; PHALP processed only its first 3 (a truncated run, as ``video.end_frame``
truncates, ``phalp/configs/base.py:17``).
"""

import numpy as np
import pytest
from pycocotools import mask as mask_utils
from scipy.spatial.transform import Rotation

from multithumbs.perception.camera import hmr2_intrinsics
from multithumbs.perception.phalp import import_phalp
from multithumbs.types import Shots

H, W = 48, 64


def _rle(x0, y0, x1, y1):
    # PHALP.py:350-353: encode an (H, W, 1) Fortran uint8 mask, then decode counts to str.
    m = np.zeros((H, W, 1), np.uint8, order="F")
    m[y0:y1, x0:x1] = 1
    rles = mask_utils.encode(m)
    for rle in rles:
        rle["counts"] = rle["counts"].decode("utf-8")
    return rles


def _entry(rotvec_z, betas0, camera, bbox, hip_xy, mask):
    joints2d = np.zeros((45, 2), np.float32)
    joints2d[8] = hip_xy             # OpenPose mid-hip (HMR2's joint 8) = the SMPL pelvis
    joints2d[4] = (1.2, 0.5)         # right wrist projected outside the padded square
    return {
        # PHALP.py:441-468 (the Detection's data), copied into the frame's lists at PHALP.py:221-226.
        "bbox": np.array(bbox, np.float32),                                   # [x, y, w, h], PHALP.py:442
        "mask": mask,                                                         # PHALP.py:443
        "conf": np.float32(0.98),                                             # detector score, PHALP.py:444
        "center": np.array([bbox[0] + bbox[2] / 2, bbox[1] + bbox[3] / 2], np.float32),  # padded box, :452
        "scale": np.array([bbox[3] * 0.75, bbox[3]], np.float32),             # padded to 192:256, :453
        "smpl": {"global_orient": Rotation.from_rotvec([0, 0, rotvec_z]).as_matrix()[None].astype(np.float32),
                 "body_pose": np.tile(np.eye(3, dtype=np.float32), (23, 1, 1)),
                 "betas": np.full(10, betas0, np.float32)},                    # rotation matrices, :454
        "camera": np.array(camera, np.float32),                               # pred_cam_t, :455
        "camera_bbox": np.array([0.9, 0.0, 0.1], np.float32),                 # weak perspective, :456
        "3d_joints": np.zeros((45, 3), np.float32),                           # :457
        "2d_joints": joints2d.reshape(-1),                                    # projections / 256, :458 (/ render.res at :430)
        "size": [H, W],                                                       # :459
        "class_name": 0, "annotations": [], "extra_data": None,
    }


def _frame(t, shot=0):
    # PHALP.py:208-210: every frame gets time (0-based), shot and frame_path, then empty lists.
    name = f"outputs//_DEMO/clip/img/{t + 1:06d}.jpg"   # '%06d' % (img_cnt + 1), phalp/utils/utils.py:176
    keys = ["tid", "bbox", "tracked_time", "tracked_ids", "tracked_bbox", "center", "scale", "size", "img_path",
            "img_name", "class_name", "conf", "annotations", "smpl", "camera", "camera_bbox", "3d_joints",
            "2d_joints", "mask", "extra_data"]                                # PHALP.py:141-145
    return name, {"time": t, "shot": shot, "frame_path": name, **{k: [] for k in keys}}


def _add(frame, tid, tracked_time, entry):
    frame["tid"].append(tid)                                                  # PHALP.py:221
    frame["tracked_time"].append(tracked_time)                                # time_since_update, :223
    for key, value in entry.items():
        frame[key].append(value)
    frame["img_path"].append(frame["frame_path"])
    frame["img_name"].append(frame["frame_path"].split("/")[-1])
    if tracked_time == 0:                                                     # PHALP.py:228-230
        frame["tracked_ids"].append(tid)
        frame["tracked_bbox"].append(entry["bbox"])


@pytest.fixture
def upstream_results():
    a0 = _entry(0.1, 0.5, [0.01, 0.02, 40.0], [10.0, 4.0, 20.0, 40.0], (0.5, 0.5), _rle(10, 4, 30, 44))
    a1 = _entry(0.2, 1.5, [0.03, 0.02, 41.0], [12.0, 4.0, 20.0, 40.0], (0.55, 0.5), _rle(12, 4, 32, 44))
    b2 = _entry(-0.3, -1.0, [-0.2, 0.0, 50.0], [40.0, 6.0, 16.0, 36.0], (0.8, 0.45), _rle(40, 6, 56, 42))
    results = {}
    for t in range(3):
        name, frame = _frame(t, shot=int(t == 2))   # shot = 1 only with detect_shots (PHALP.py:186)
        results[name] = frame
    f0, f1, f2 = results.values()
    _add(f0, 1, 0, a0)        # track 1 back-filled into its first frames once confirmed (PHALP.py:232-244)
    _add(f1, 1, 0, a1)
    _add(f2, 1, 1, a1)        # ghost: lost in frame 2, listed with frame 1's stale values
    _add(f2, 3, 0, b2)        # ids count from 1 and need not be consecutive
    return results


def test_upstream_file_loads_field_by_field(upstream_results):
    shots = Shots(np.zeros(0, np.int64), 30.0, 4, np.zeros(4))
    imported = import_phalp(upstream_results, shots, (H, W), video_name="clip")
    (tr,) = imported.tracks
    np.testing.assert_array_equal(tr.track_ids, [1, 3])
    # Placed by time: frames 0-2; frame 3 was not processed; the ghost in frame 2 is not a detection.
    np.testing.assert_array_equal(tr.valid, [[True, True, False, False], [False, False, True, False]])
    np.testing.assert_allclose(tr.global_orient[0, :2], [[0, 0, 0.1], [0, 0, 0.2]], atol=1e-6)
    np.testing.assert_allclose(tr.global_orient[1, 2], [0, 0, -0.3], atol=1e-6)
    np.testing.assert_allclose(tr.body_pose[tr.valid], 0.0, atol=1e-6)
    np.testing.assert_allclose(tr.betas, [np.full(10, 1.0), np.full(10, -1.0)], atol=1e-6)  # mean over frames
    np.testing.assert_allclose(tr.transl[0, 1], [0.03, 0.02, 41.0], atol=1e-5)  # HMR2's camera, kept
    # ... with HMR2's intrinsics: focal 5000 / 256 * max(H, W), principal point at the padded square's
    # centre (the frame is padded by (64 - 48) // 2 = 8 rows on top), integer pixel centres.
    np.testing.assert_allclose(tr.K, hmr2_intrinsics((H, W)))
    np.testing.assert_allclose(tr.K[:2, :], [[1250, 0, 31.5], [0, 1250, 23.5]])
    np.testing.assert_allclose(imported.boxes[0][0, 1], [11.5, 3.5, 31.5, 43.5])  # x,y,w,h -> x0,y0,x1,y1 - 0.5
    # 2d_joints (normalised to the padded square) in pixels: u = x * 64 - 0.5, v = y * 64 - 8 - 0.5.
    np.testing.assert_allclose(tr.keypoints2d[0, 0, 0], [31.5, 23.5, 1.0])
    np.testing.assert_allclose(tr.keypoints2d[0, 1, 0], [34.7, 23.5, 1.0], atol=1e-4)
    np.testing.assert_allclose(tr.keypoints2d[1, 2, 0], [50.7, 20.3, 1.0], atol=1e-4)
    assert tr.keypoints2d[0, 0, 21, 2] == 0          # the right wrist projects outside the image
    assert tr.keypoints2d[0, 0, 3, 2] == 0           # spine: no OpenPose counterpart
    m = tr.mask(0, 1)
    assert m.sum() == 20 * 40 and m[4:44, 12:32].all()
    assert tr.mask(1, 2)[6:42, 40:56].all() and not tr.mask(0, 2).any()
    assert imported.uv_appearance is None             # appe only when PHALP rendered (render.enable)
    np.testing.assert_array_equal(imported.phalp_cut_frames, [2])
