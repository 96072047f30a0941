"""Perfect 3D written the way 4DHumans/PHALP writes its results, run through the method from pixels.

For each scene: synthesise it, simulate PERFECT perception (truth in each shot's camera), write it as an
upstream-shaped PHALP file (:func:`multithumbs.perception.phalp_export.export_phalp`: 1-based names, ``time``,
HMR2-camera ``2d_joints``, ghosts, confirmation), then run the plain-Python chain of ``multithumbs run``
(cuts by scenedetect, geometry by pycolmap, true intrinsics) with the file's 2D joints taken each way of
:data:`multithumbs.perception.model_keypoints.KEYPOINT_MODES`, and with the oracle perception
(``oracle:GT.npz``) for reference. ``--truncate N`` also keeps only the file's first N frames.

    python benchmarks/phalp_upstream.py [--scene clip50] [--modes reproject,as_is,none] [--json OUT]
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

CLIP = dict(name="clip50", num_people=2, num_shots=2, num_frames=50, seed=7, image_size=(180, 320),
            cut_angle_deg=35)
"""The 50-frame clip of issue 15 (the from-pixels flow test's scene, longer)."""


def run(perception: str, video_path: Path, K, body, truth, cuts=None, mode: str = "reproject") -> dict:
    import numpy as np

    from multithumbs.metrics.evaluate import evaluate
    from multithumbs.perception import load_perception
    from multithumbs.pipeline import MethodConfig, run_video
    from multithumbs.scene.geometry import scene_geometry
    from multithumbs.scene.shots import detect_shots
    from multithumbs.video import read_frames

    shots = detect_shots(video_path)
    tracks = load_perception(perception, video_path, shots, trust=True, intrinsics=K, model_keypoints=mode,
                             body=body)
    geometry = scene_geometry(read_frames(video_path), shots, K, np.concatenate([tr.people_mask() for tr in tracks]))
    result = run_video(shots, tracks, list(geometry.trajectories), list(geometry.spaces), body, MethodConfig())
    scores = evaluate(result, truth, body)
    return {k: float(scores[k]) for k in ("w_mpjpe", "wa_mpjpe", "mpjpe", "ids", "coverage") if k in scores}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default="clip50", help="clip50 or a standard-suite scene name")
    parser.add_argument("--modes", default="reproject,as_is,none")
    parser.add_argument("--truncate", type=int, default=0)
    parser.add_argument("--json", default="")
    args = parser.parse_args()

    import joblib
    import torch

    torch.set_num_threads(2)
    from multithumbs.body.model import load_body_model
    from multithumbs.perception.phalp_export import export_phalp
    from multithumbs.synth.files import write_synthetic
    from multithumbs.synth.perception import NO_NOISE, simulate_perception
    from multithumbs.synth.scene import SceneConfig, synthesize
    from multithumbs.synth.suite import suite_scene

    body = load_body_model()
    config = SceneConfig(**CLIP) if args.scene == "clip50" else suite_scene("standard", args.scene)
    video = synthesize(config, body)
    truth = video.truth
    K = truth.world.K[0]
    out = {"scene": args.scene, "frames": config.num_frames}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        write_synthetic(tmp, video)
        tracks = simulate_perception(video, body, NO_NOISE)
        pkl = export_phalp(tmp / "results.pkl", tracks, truth.world.shots(), body)
        start = time.perf_counter()
        out["oracle"] = run(f"oracle:{tmp / 'ground_truth.npz'}", tmp / "video.mp4", K, body, truth)
        out["seconds_per_run"] = time.perf_counter() - start
        for mode in [m for m in args.modes.split(",") if m]:
            out[f"phalp/{mode}"] = run(f"phalp:{pkl}", tmp / "video.mp4", K, body, truth, mode=mode)
        if args.truncate:
            results = {k: v for k, v in joblib.load(pkl).items() if v["time"] < args.truncate}
            joblib.dump(results, tmp / "truncated.pkl", compress=3)
            out[f"phalp/reproject truncated to {args.truncate}"] = run(f"phalp:{tmp / 'truncated.pkl'}",
                                                                       tmp / "video.mp4", K, body, truth)
    print(json.dumps(out, indent=2))
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
