"""Our metrics against the field's own evaluation code, on identical perturbed arrays.

The references are not shipped with this project: point the script at a checkout of GVHMR
(``hmr4d/utils/eval/eval_utils.py`` is loaded from it by path; it needs only torch and numpy). evo (ATE)
and TrackEval (IDs) are installed by ``scripts/setup.sh``. Scenarios: noise, a Sim(3) offset per person,
drift, missing frames, overlapping and swapped people, camera drift, two sequences. Prints, per metric and
scenario, our value, the reference's and their relative difference; exits 1 when one exceeds ``--rtol``.

    .venv/bin/python benchmarks/reference_metrics.py --gvhmr PATH/TO/GVHMR [--rtol 1e-6]

GVHMR's protocol (``compute_global_metrics``, ``compute_camcoord_metrics``) takes one person's masked
frames at a time; ours takes padded ``(P, T)`` arrays. The comparison feeds each person's valid frames to
GVHMR and concatenates its per-frame values, as its evaluation loop does.
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
from pathlib import Path

import multithumbs  # noqa: F401  (before numpy and torch: it pins the CPU kernels, multithumbs/cpu_kernels.py)
import numpy as np
import torch

from multithumbs.geometry import Similarity
from multithumbs.metrics.alignment import ValidFrames, apply_similarity
from multithumbs.metrics.camera import absolute_trajectory_error
from multithumbs.metrics.gt_free import jitter
from multithumbs.metrics.identity import associate_by_iou, count_id_switches
from multithumbs.metrics.pose import accel, foot_sliding_against_truth, mpjpe, pa_mpjpe, w_mpjpe, wa_mpjpe

FEET = [3216, 3387, 6617, 6787]
FPS = 30.0


def load_gvhmr(root: Path):
    path = root / "hmr4d/utils/eval/eval_utils.py"
    if not path.is_file():
        sys.exit(f"--gvhmr {root}: no hmr4d/utils/eval/eval_utils.py there (a GVHMR checkout is expected)")
    spec = importlib.util.spec_from_file_location("gvhmr_eval_utils", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def random_similarity(rng: np.random.Generator) -> Similarity:
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    w, x, y, z = q
    rot = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                    [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                    [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
    return Similarity.from_numpy(rng.uniform(0.5, 2.0), rot, rng.normal(0.0, 3.0, 3))


def scenario(rng: np.random.Generator, name: str, p: int = 3, t: int = 240):
    """Truth and prediction: world joints, camera-frame joints, feet, validity, camera centres."""
    base = rng.normal(size=(p, 1, 24, 3)) * 0.3
    true = base + np.cumsum(rng.normal(size=(p, t, 1, 3)) * 0.02, axis=1) \
        + 0.02 * np.sin(np.arange(t) / 4.0)[None, :, None, None] * rng.normal(size=(p, 1, 24, 3))
    pred = true.copy()
    valid = np.ones((p, t), bool)
    if name in ("noise", "missing", "sim3", "two_sequences"):
        pred = pred + rng.normal(size=pred.shape) * 0.03
    if name in ("sim3", "drift", "two_sequences"):
        for k in range(p):
            pred[k] = apply_similarity(random_similarity(rng), pred[k].reshape(-1, 3)).reshape(t, 24, 3)
    if name == "drift":
        pred = pred + np.linspace(0.0, 0.5, t)[None, :, None, None] * np.array([1.0, 0.2, 0.0])
    if name in ("missing", "two_sequences"):
        valid = rng.random((p, t)) > 0.2
        valid[0, 60:130] = False
    cam_true = np.cumsum(rng.normal(size=(t, 3)) * 0.05, axis=0)
    cam_pred = apply_similarity(random_similarity(rng), cam_true) + np.cumsum(rng.normal(size=(t, 3)) * 0.01, axis=0)
    # Camera frames: the truth seen from a rotating camera, the prediction with an extra small rotation.
    true_cam = true + np.array([0.0, 0.0, 4.0])
    pred_cam = pred - pred[:, :, [1, 2]].mean(axis=2, keepdims=True) + true_cam[:, :, [1, 2]].mean(axis=2, keepdims=True)
    pred_cam = pred_cam + rng.normal(size=pred_cam.shape) * 0.01
    feet_true = true[:, :, [7, 8, 10, 11]].copy()
    feet_true[:, :, :2] = feet_true[:, :1, :2]  # two of four foot points rest
    feet_pred = feet_true + rng.normal(size=feet_true.shape) * 0.004
    return dict(true=true, pred=pred, true_cam=true_cam, pred_cam=pred_cam, feet_true=feet_true,
                feet_pred=feet_pred, valid=valid, cam_true=cam_true, cam_pred=cam_pred)


def ours(s) -> dict[str, float]:
    v = s["valid"]
    return {
        "w_mpjpe": w_mpjpe(s["pred"], s["true"], v).mean(),
        "wa_mpjpe": wa_mpjpe(s["pred"], s["true"], v).mean(),
        "mpjpe": mpjpe(s["pred_cam"], s["true_cam"], v).mean(),
        "pa_mpjpe": pa_mpjpe(s["pred_cam"], s["true_cam"], v).mean(),
        "accel": accel(s["pred_cam"], s["true_cam"], v, FPS).mean(),
        "jitter": jitter(s["pred"], v, FPS).mean(),
        "fs_gt": foot_sliding_against_truth(s["feet_pred"], s["feet_true"], v).mean(),
        "ate": absolute_trajectory_error(s["cam_pred"], s["cam_true"]).rmse,
    }


def _verts(feet: np.ndarray) -> torch.Tensor:
    """GVHMR's foot sliding reads SMPL vertices: the foot points at the foot vertex ids of a (F, 6890, 3)."""
    verts = np.zeros((len(feet), 6890, 3))
    verts[:, FEET] = feet
    return torch.from_numpy(verts)


def reference(s, gvhmr) -> dict[str, float]:
    values = {k: [] for k in ("w_mpjpe", "wa_mpjpe", "mpjpe", "pa_mpjpe", "accel", "jitter", "fs_gt")}
    tensor = lambda a: torch.from_numpy(np.ascontiguousarray(a))
    for k in range(len(s["valid"])):
        mask = tensor(s["valid"][k])
        glob = gvhmr.compute_global_metrics({
            "pred_j3d_glob": tensor(s["pred"][k]), "target_j3d_glob": tensor(s["true"][k]),
            "pred_verts_glob": _verts(s["feet_pred"][k]), "target_verts_glob": _verts(s["feet_true"][k]),
        }, mask=mask)
        cam = gvhmr.compute_camcoord_metrics({
            "pred_j3d": tensor(s["pred_cam"][k]), "target_j3d": tensor(s["true_cam"][k]),
            "pred_verts": tensor(s["pred_cam"][k]), "target_verts": tensor(s["true_cam"][k]),
        }, fps=FPS, mask=mask)
        values["w_mpjpe"].append(glob["wa2_mpjpe"])
        values["wa_mpjpe"].append(glob["waa_mpjpe"])
        values["jitter"].append(glob["jitter"])
        values["fs_gt"].append(glob["fs"])
        for key in ("mpjpe", "pa_mpjpe", "accel"):
            values[key].append(np.asarray(cam[key]))
    out = {k: float(np.concatenate(v).mean()) for k, v in values.items()}
    out["ate"] = evo_ate(s["cam_pred"], s["cam_true"])
    return out


def evo_ate(est: np.ndarray, ref: np.ndarray) -> float:
    import copy

    from evo.core import metrics, trajectory

    quat = np.tile([1.0, 0.0, 0.0, 0.0], (len(est), 1))
    stamps = np.arange(len(est), dtype=float)
    traj_ref = trajectory.PoseTrajectory3D(positions_xyz=ref, orientations_quat_wxyz=quat, timestamps=stamps)
    traj_est = copy.deepcopy(trajectory.PoseTrajectory3D(positions_xyz=est, orientations_quat_wxyz=quat,
                                                         timestamps=stamps))
    traj_est.align(traj_ref, correct_scale=True)
    ape = metrics.APE(metrics.PoseRelation.translation_part)
    ape.process_data((traj_ref, traj_est))
    return float(ape.get_statistic(metrics.StatisticsType.rmse))


def id_scenarios(rng: np.random.Generator):
    """(name, true boxes, true present, pred boxes, pred present) for overlapping and swapped people."""
    box = lambda x: [x, 0.0, x + 10.0, 20.0]
    walk = lambda xs: np.array([box(x) for x in xs])
    t = 10
    overlap = (np.stack([walk([0.0] * t), walk([30.0] * 4 + [0.5, 0.5] + [30.0] * 4)]),
               np.stack([walk([0.0] * 4 + [0.3, 0.3] + [0.0] * 4), walk([30.0] * 4 + [0.2, 0.2] + [30.0] * 4)]))
    swap = (np.stack([walk([0.0] * 12), walk([50.0] * 12)]),
            np.stack([walk([0.0] * 6 + [50.0] * 6), walk([50.0] * 6 + [0.0] * 6)]))
    out = [("overlapping", overlap[0], np.ones((2, t), bool), overlap[1], np.ones((2, t), bool)),
           ("swapped", swap[0], np.ones((2, 12), bool), swap[1], np.ones((2, 12), bool))]
    xs = np.cumsum(rng.normal(0, 2.0, (3, 60)), axis=1)
    true = np.stack([walk(x) for x in xs])
    pred = true + rng.normal(0, 1.0, true.shape)
    pred[:, :, [0, 2]] = 1.5 * pred[:, :, [0, 2]]  # trajectories scaled x1.5
    out.append(("scaled_x1.5", true, rng.random((3, 60)) > 0.1, pred, rng.random((3, 60)) > 0.1))
    return out


def trackeval_idsw(true, true_present, pred, pred_present) -> int:
    from trackeval.datasets._base_dataset import _BaseDataset
    from trackeval.metrics import CLEAR

    data = {"gt_ids": [], "tracker_ids": [], "similarity_scores": []}
    for t in range(true_present.shape[1]):
        gts, preds = np.nonzero(true_present[:, t])[0], np.nonzero(pred_present[:, t])[0]
        data["gt_ids"].append(gts)
        data["tracker_ids"].append(preds)
        data["similarity_scores"].append(_BaseDataset._calculate_box_ious(true[gts, t], pred[preds, t],
                                                                          box_format="x0y0x1y1"))
    data.update(num_timesteps=true_present.shape[1], num_gt_ids=len(true), num_tracker_ids=len(pred),
                num_gt_dets=int(true_present.sum()), num_tracker_dets=int(pred_present.sum()))
    return int(CLEAR({"PRINT_CONFIG": False}).eval_sequence(data)["IDSW"])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--gvhmr", type=Path, required=True, help="a GVHMR checkout (its eval_utils.py is loaded)")
    parser.add_argument("--rtol", type=float, default=1e-6)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    gvhmr = load_gvhmr(args.gvhmr)
    # GVHMR builds helper tensors (torch.eye, torch.ones) in the default dtype: float64 keeps its Umeyama in
    # double precision, as ours is, so the comparison measures the protocol and not float32 rounding.
    torch.set_default_dtype(torch.float64)
    rng = np.random.default_rng(args.seed)
    worst = 0.0
    print(f"{'scenario':14} {'metric':9} {'ours':>14} {'reference':>14} {'rel. diff':>10}")
    for name in ("noise", "sim3", "drift", "missing"):
        s = scenario(rng, name)
        a, b = ours(s), reference(s, gvhmr)
        for key in a:
            rel = abs(a[key] - b[key]) / max(abs(b[key]), 1e-12)
            worst = max(worst, rel)
            print(f"{name:14} {key:9} {a[key]:14.8f} {b[key]:14.8f} {rel:10.1e}")
    # Two sequences: ATE is the mean of per-sequence values.
    seqs = [scenario(rng, "two_sequences") for _ in range(2)]
    ours_ate = float(np.mean([absolute_trajectory_error(s["cam_pred"], s["cam_true"]).rmse for s in seqs]))
    ref_ate = float(np.mean([evo_ate(s["cam_pred"], s["cam_true"]) for s in seqs]))
    rel = abs(ours_ate - ref_ate) / ref_ate
    worst = max(worst, rel)
    print(f"{'two_sequences':14} {'ate':9} {ours_ate:14.8f} {ref_ate:14.8f} {rel:10.1e}")
    for name, true, tp, pred, pp in id_scenarios(rng):
        mine = count_id_switches(associate_by_iou(true, tp, pred, pp)).total
        ref = trackeval_idsw(true, tp, pred, pp)
        worst = max(worst, float(mine != ref))
        print(f"{name:14} {'ids':9} {mine:14d} {ref:14d} {'equal' if mine == ref else 'DIFFERENT':>10}")
    print(f"worst relative difference {worst:.1e} (rtol {args.rtol:g})")
    sys.exit(0 if worst <= args.rtol else 1)


if __name__ == "__main__":
    main()
