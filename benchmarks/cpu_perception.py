"""The CPU perception backend (BlazePose + body fitting) against the rendered truth of the standard suite.

Every scene is rendered; the backend sees only its frames (true cuts and true intrinsics are given, so
this measures perception alone). Printed per scene and over the suite:

* detection recall and precision (IoU ≥ 0.5 of the boxes of the meshes' silhouettes in the frame; recall
  over people ≥ 80 px tall with at least half their silhouette seen; ``multithumbs.metrics.perception``);
* 2D PCK@0.1 of the box size on the joints the truth marks visible;
* identity switches within shots: CLEAR-MOT's count (``multithumbs.metrics.identity.count_id_switches``)
  over the per-frame matching of the recall figure (each fragment of a person lost and found again under a
  new id counts one);
* per-frame MPJPE and PA-MPJPE (mm, pelvis-aligned camera-frame joints) of the fitted bodies;
* seconds per frame, split into the person detector (NanoDet, whose boxes are the tracker's proposals),
  landmarks (BlazePose's detector + landmark model + tracking) and fitting;
* with ``--misses``, the eligible person-frames left unpaired, by why and where
  (``multithumbs.metrics.perception.miss_kinds``): nobody near, a track whose box is off, or a track
  paired with someone overlapping; before the person's first paired frame, between two, after the last.

    .venv/bin/python benchmarks/cpu_perception.py [--scenes s01_two_people_20deg,...] [--runs 1]
        [--no-fit] [--no-facing] [--no-ground] [--no-head] [--no-behind] [--no-bridge]
        [--detector nanodet|hog] [--misses] [--json OUT]
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "2")

import argparse
import dataclasses
import json
import statistics
import time

import multithumbs  # noqa: F401  (before numpy and torch: it pins the CPU kernels, multithumbs/cpu_kernels.py)
import numpy as np


def padded_landmark_boxes(boxes: np.ndarray, image_size: tuple[int, int]) -> np.ndarray:
    """Landmark boxes widened to the body's surface, for ``--no-fit``: landmarks are joint centres and
    face points, so the skin lies ~10 % of the height beyond them at the sides and above the eyes."""
    h, w = image_size
    height = (boxes[..., 3] - boxes[..., 1])[..., None]
    padded = boxes + height * np.array([-0.1, -0.12, 0.1, 0.02])
    return np.clip(padded, -0.5, [w - 0.5, h - 0.5, w - 0.5, h - 0.5])


def score_scene(name: str, fit: bool = True, facing: bool = True, ground: bool = True,
                detector: str = "nanodet", head: bool = True, behind: bool = True, bridge: bool = True) -> dict:
    import torch

    from multithumbs.body.model import load_body_model
    from multithumbs.determinism import fix_threads
    from multithumbs.metrics.identity import count_id_switches
    from multithumbs.metrics.perception import (detection_counts, eligible_people, match_people, miss_kinds, pck,
                                                silhouette_boxes)
    from multithumbs.metrics.pose import mpjpe, pa_mpjpe
    from multithumbs.perception.blazepose_backend import (BlazePoseConfig, poses_to_tracks, shot_face_evidence,
                                                          shot_floor_flow)
    from multithumbs.perception.blazepose_models import BlazePose
    from multithumbs.perception.joints import BLAZEPOSE_SMPL_JOINTS
    from multithumbs.perception.oracle import oracle_tracks
    from multithumbs.perception.blazepose_backend import person_proposals
    from multithumbs.perception.pose_tracking import track_shot
    from multithumbs.synth.scene import synthesize
    from multithumbs.synth.suite import suite_scene

    # The one thread count `run` and the bench compute with (multithumbs.determinism): set here, before the
    # first shot's detector runs, since the body model's loading sets it only once per process. With torch's
    # 2 threads restored per scene instead, a scene's first shot was detected at 2 threads except in the
    # first scene, so a scene scored differently alone and after others (s04: PCK 0.793 against 0.788).
    fix_threads()
    body = load_body_model()
    video = synthesize(suite_scene("standard", name), body)
    truth = oracle_tracks(video.truth, body, video.instance)
    K = video.truth.world.K[0]
    model = BlazePose(num_threads=2)
    config = dataclasses.replace(BlazePoseConfig(), person_detector=detector)
    if not facing:
        config = dataclasses.replace(config, facing=dataclasses.replace(config.facing, enabled=False))
    if not ground:
        config = dataclasses.replace(config, ground=dataclasses.replace(config.ground, enabled=False))
    if not head:
        config = dataclasses.replace(config, head=dataclasses.replace(config.head, enabled=False))
    if not behind:
        config = dataclasses.replace(config, tracker=dataclasses.replace(config.tracker, read_behind=False))
    if not bridge:
        config = dataclasses.replace(config, gaps=dataclasses.replace(config.gaps, max_gap=0))
    seconds = {"landmarks": 0.0, "detection": 0.0, "fitting": 0.0}
    proposals = person_proposals(config, seconds=seconds)
    tallies = np.zeros(4, np.int64)
    correct = counted = 0
    errors, pa_errors = [], []
    frames = switches = 0
    misses: dict[str, int] = {}
    for true_tr, (a, b) in zip(truth, video.truth.world.shots().ranges):
        start, detected = time.perf_counter(), seconds["detection"]
        poses = track_shot(video.frames[a:b], model, config.tracker, people=proposals)
        seconds["landmarks"] += time.perf_counter() - start - (seconds["detection"] - detected)
        frames += b - a
        with torch.no_grad():
            out = body.forward(true_tr.global_orient, true_tr.body_pose, true_tr.betas, true_tr.transl)
        true_vertices, true_joints = out.vertices.double().numpy(), out.joints.double().numpy()
        visible = np.unpackbits(true_tr.masks, axis=-1).sum((-1, -2))
        true_boxes, eligible = eligible_people(true_vertices, body.faces, K, video.truth.world.image_size, visible,
                                               true_tr.valid)
        h, w = video.truth.world.image_size
        if fit:
            start = time.perf_counter()
            floor_flow = shot_floor_flow(video.frames[a:b], poses, config)
            face = shot_face_evidence(video.frames[a:b], poses, config)
            tracks = poses_to_tracks(poses, true_tr.shot_index, a, K, (h, w), body, config.fit, config.facing,
                                     floor_flow, face, config.floor, config.gaps)
            seconds["fitting"] += time.perf_counter() - start
            pred_kp = tracks.keypoints2d
            with torch.no_grad():
                fitted = body.forward(tracks.global_orient, tracks.body_pose, tracks.betas, tracks.transl)
            # The fitted mesh's silhouette in the frame, the same kind of box as the truth's.
            pred_boxes, _ = silhouette_boxes(fitted.vertices.double().numpy(), body.faces, K, (h, w))
        else:
            from multithumbs.perception.joints import blazepose33_to_smpl24

            pred_kp = blazepose33_to_smpl24(np.concatenate([poses.image[..., :2], poses.image[..., 3:4]], -1))
            pred_boxes = padded_landmark_boxes(poses.boxes, (h, w))
        pred_valid = tracks.valid if fit else poses.valid  # the fit drops tracks of no one (floor_check)
        matched = match_people(pred_boxes, pred_valid, true_boxes, true_tr.valid)
        counts = detection_counts(matched, eligible, pred_valid)
        tallies += [counts.true_positives, counts.eligible, counts.predictions, counts.false_positives]
        switches += count_id_switches(matched).total
        for (kind, place), n in miss_kinds(matched, eligible, true_boxes, pred_boxes, pred_valid).items():
            misses[f"{kind}/{place}"] = misses.get(f"{kind}/{place}", 0) + n
        people, times = np.nonzero((matched >= 0) & eligible)
        pred_index = matched[people, times]
        joints = np.zeros(24, bool)
        joints[list(BLAZEPOSE_SMPL_JOINTS)] = True
        true_kp = true_tr.keypoints2d[people, times]
        size = np.maximum(true_boxes[people, times, 2] - true_boxes[people, times, 0],
                          true_boxes[people, times, 3] - true_boxes[people, times, 1])
        c, n = pck(pred_kp[pred_index, times, :, :2], true_kp[..., :2], (true_kp[..., 2] > 0) & joints, size)
        correct, counted = correct + c, counted + n
        if fit and people.size:
            with torch.no_grad():
                pj = body.joints(tracks.global_orient, tracks.body_pose, tracks.betas, tracks.transl).double().numpy()
            pair_pred = pj[pred_index, times][None]
            pair_true = true_joints[people, times][None]
            ok = np.ones((1, people.size), bool)
            errors.append(np.asarray(mpjpe(pair_pred, pair_true, ok).values).ravel())
            pa_errors.append(np.asarray(pa_mpjpe(pair_pred, pair_true, ok).values).ravel())
    tp, eligible_n, predictions, fp = (int(x) for x in tallies)
    return {
        "scene": name, "recall": tp / eligible_n if eligible_n else float("nan"),
        "precision": 1 - fp / predictions if predictions else float("nan"), "eligible": eligible_n,
        "pck": correct / counted if counted else float("nan"),
        "mpjpe": float(np.concatenate(errors).mean()) if errors else float("nan"),
        "pa_mpjpe": float(np.concatenate(pa_errors).mean()) if pa_errors else float("nan"),
        "landmark_s_per_frame": seconds["landmarks"] / frames, "detection_s_per_frame": seconds["detection"] / frames,
        "fit_s_per_frame": seconds["fitting"] / frames,
        "people": int(video.truth.world.valid.shape[0]), "switches": switches, "misses": misses,
    }


def _print_misses(rows: list[dict]) -> None:
    """Missed person-frames per scene: by why (none, box_off, taken), then by where (before, between, after,
    never), and all of them."""
    from multithumbs.metrics.perception import MISS_KINDS, MISS_PLACES

    def total(row: dict, part: str) -> int:
        return sum(n for key, n in row["misses"].items() if part in key.split("/"))

    columns = MISS_KINDS + MISS_PLACES
    print(f"\n{'missed frames':<14} " + " ".join(f"{c:>7}" for c in columns) + f" {'all':>5}")
    for row in rows + [{"scene": "all", "misses": {k: sum(r["misses"][k] for r in rows) for k in rows[0]["misses"]}}]:
        print(f"{row['scene'][:14]:<14} " + " ".join(f"{total(row, c):>7}" for c in columns)
              + f" {sum(row['misses'].values()):>5}")


def main() -> None:
    from multithumbs.synth.suite import suite

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", default=None, help="comma-separated scene names (default: all 12)")
    parser.add_argument("--runs", type=int, default=1, help="runs of the whole measurement; medians are quoted")
    parser.add_argument("--no-fit", action="store_true", help="tracking and 2D only (no body fitting)")
    parser.add_argument("--no-facing", action="store_true",
                        help="keep BlazePose's readings as they are (no mirroring by the walk)")
    parser.add_argument("--no-ground", action="store_true",
                        help="read the walk in the camera frame (the camera's motion not taken out by the floor)")
    parser.add_argument("--no-head", action="store_true",
                        help="label front and back without the head's colours (multithumbs/perception/head_colour.py)")
    parser.add_argument("--no-behind", action="store_true",
                        help="do not read a lost person's square again with the others greyed out "
                             "(multithumbs/perception/behind.py)")
    parser.add_argument("--no-bridge", action="store_true",
                        help="leave the gaps inside a track empty (multithumbs/perception/gap_fill.py)")
    parser.add_argument("--detector", default="nanodet", choices=("nanodet", "hog"),
                        help="where the tracker's person proposals come from")
    parser.add_argument("--misses", action="store_true",
                        help="also print the missed person-frames by why and where (first run)")
    parser.add_argument("--json", default=None, help="write the per-scene results here")
    args = parser.parse_args()
    names = args.scenes.split(",") if args.scenes else [s.name for s in suite("standard")]
    runs = [[score_scene(n, fit=not args.no_fit, facing=not args.no_facing, ground=not args.no_ground,
                         detector=args.detector, head=not args.no_head,
                         behind=not args.no_behind, bridge=not args.no_bridge) for n in names]
            for _ in range(args.runs)]
    rows = runs[0]
    keys = ("recall", "precision", "switches", "pck", "mpjpe", "pa_mpjpe", "detection_s_per_frame",
            "landmark_s_per_frame", "fit_s_per_frame")
    print(f"{'scene':<32} {'P':>2} {'recall':>6} {'prec':>6} {'IDsw':>4} {'PCK':>6} {'MPJPE':>6} {'PA':>6} "
          f"{'det s/f':>7} {'lm s/f':>7} {'fit s/f':>7}")
    for i, row in enumerate(rows):
        med = {k: statistics.median(run[i][k] for run in runs) for k in keys}
        print(f"{row['scene']:<32} {row['people']:>2} {med['recall']:6.3f} {med['precision']:6.3f} "
              f"{med['switches']:4.0f} {med['pck']:6.3f} {med['mpjpe']:6.1f} {med['pa_mpjpe']:6.1f} "
              f"{med['detection_s_per_frame']:7.3f} {med['landmark_s_per_frame']:7.3f} {med['fit_s_per_frame']:7.3f}")
    total = {k: statistics.median(statistics.fmean(r[k] for r in run) for run in runs) for k in keys}
    print(f"{'mean':<32} {'':>2} {total['recall']:6.3f} {total['precision']:6.3f} {total['switches']:4.1f} "
          f"{total['pck']:6.3f} {total['mpjpe']:6.1f} {total['pa_mpjpe']:6.1f} "
          f"{total['detection_s_per_frame']:7.3f} {total['landmark_s_per_frame']:7.3f} {total['fit_s_per_frame']:7.3f}")
    if args.misses:
        _print_misses(rows)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(runs, f, indent=1)


if __name__ == "__main__":
    main()
