"""The tracker's two person detectors alone (NanoDet, OpenCV's HOG) against the standard suite's rendered truth.

No tracking and no landmarks: each detector's boxes on every ``--every``-th frame are matched to the boxes of
the true meshes' silhouettes in the frame (IoU ≥ 0.5, ``multithumbs.metrics.perception``), with the same
eligibility as ``benchmarks/cpu_perception.py`` (people ≥ 80 px tall with at least half their silhouette in
the frame). Printed per scene: recall, precision and seconds per frame of each detector.

    .venv/bin/python benchmarks/person_detectors.py [--scenes s04_three_people_60deg_moving,...]
        [--every 2] [--nanodet-score 0.35]
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "2")

import argparse
import time

import multithumbs  # noqa: F401  (before numpy and torch: it pins the CPU kernels)
import numpy as np


def score_scene(name: str, every: int, nanodet_score: float) -> dict[str, tuple[float, float, float]]:
    """Detector -> (recall, precision, seconds per frame) on one scene."""
    import torch

    from multithumbs.body.model import load_body_model
    from multithumbs.metrics.perception import detection_counts, eligible_people, match_people
    from multithumbs.perception.nanodet import NanoDet
    from multithumbs.perception.oracle import oracle_tracks
    from multithumbs.perception.person_proposals import hog_boxes
    from multithumbs.perception.tracker_config import TrackerConfig
    from multithumbs.synth.scene import synthesize
    from multithumbs.synth.suite import suite_scene

    torch.set_num_threads(2)
    body = load_body_model()
    nanodet, tracker = NanoDet(), TrackerConfig()
    detectors = {"nanodet": lambda f: nanodet.people(f, nanodet_score),
                 "hog": lambda f: hog_boxes(f, tracker.proposal_scales, tracker.proposal_min_weight)}
    video = synthesize(suite_scene("standard", name), body)
    truth = oracle_tracks(video.truth, body, video.instance)
    K = video.truth.world.K[0]
    tallies = {k: np.zeros(4, np.int64) for k in detectors}
    seconds = dict.fromkeys(detectors, 0.0)
    frames = 0
    for true_tr, (a, b) in zip(truth, video.truth.world.shots().ranges):
        with torch.no_grad():
            out = body.forward(true_tr.global_orient, true_tr.body_pose, true_tr.betas, true_tr.transl)
        visible = np.unpackbits(true_tr.masks, axis=-1).sum((-1, -2))
        true_boxes, eligible = eligible_people(out.vertices.double().numpy(), body.faces, K,
                                               video.truth.world.image_size, visible, true_tr.valid)
        times = np.arange(0, b - a, every)
        frames += len(times)
        for key, detect in detectors.items():
            found = []
            for t in times:
                start = time.perf_counter()
                found.append(detect(video.frames[a + t]))
                seconds[key] += time.perf_counter() - start
            n = max([len(x) for x in found] + [1])
            boxes, valid = np.zeros((n, len(times), 4)), np.zeros((n, len(times)), bool)
            for j, x in enumerate(found):
                boxes[:len(x), j], valid[:len(x), j] = x[:, :4], True
            matched = match_people(boxes, valid, true_boxes[:, times], true_tr.valid[:, times])
            counts = detection_counts(matched, eligible[:, times], valid)
            tallies[key] += [counts.true_positives, counts.eligible, counts.predictions, counts.false_positives]
    return {key: (tp / e if e else float("nan"), 1 - fp / p if p else float("nan"), seconds[key] / frames)
            for key, (tp, e, p, fp) in tallies.items()}


def main() -> None:
    from multithumbs.synth.suite import suite

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", default=None, help="comma-separated scene names (default: all 12)")
    parser.add_argument("--every", type=int, default=2, help="score every n-th frame")
    parser.add_argument("--nanodet-score", type=float, default=0.35, help="NanoDet's person score threshold")
    args = parser.parse_args()
    names = args.scenes.split(",") if args.scenes else [s.name for s in suite("standard")]
    print(f"{'scene':<32} {'NanoDet rec':>11} {'prec':>5} {'s/f':>5}   {'HOG rec':>7} {'prec':>5} {'s/f':>5}")
    rows = []
    for name in names:
        row = score_scene(name, args.every, args.nanodet_score)
        rows.append(row)
        (nr, np_, ns), (hr, hp, hs) = row["nanodet"], row["hog"]
        print(f"{name:<32} {nr:11.3f} {np_:5.3f} {ns:5.3f}   {hr:7.3f} {hp:5.3f} {hs:5.3f}", flush=True)
    mean = {k: np.mean([r[k] for r in rows], axis=0) for k in ("nanodet", "hog")}
    print(f"{'mean':<32} {mean['nanodet'][0]:11.3f} {mean['nanodet'][1]:5.3f} {mean['nanodet'][2]:5.3f}   "
          f"{mean['hog'][0]:7.3f} {mean['hog'][1]:5.3f} {mean['hog'][2]:5.3f}")


if __name__ == "__main__":
    main()
