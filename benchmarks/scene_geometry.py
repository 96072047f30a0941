"""Scene geometry from pixels: accuracy on the standard suite and speed on a 150-frame clip.

Usage: python benchmarks/scene_geometry.py [--runs N] [--scenes a,b] [--skip-suite] [--skip-sweep] [--skip-speed]

Prints, for the standard suite (``multithumbs.synth.suite.suite("standard")``):
  * cuts: detected (adaptive, from the frames and from the encoded mp4) vs true cut frames, false cuts;
  * shared spaces: per cut, the relative rotation error and translation-direction error of the two
    boundary cameras against the truth, which path ran; medians over cuts with cut angle <= 60 deg;
  * camera trajectories: ATE (Sim(3)-aligned camera centres, RMSE) of moving-camera shots as a percentage
    of the trajectory length, and the static detection of the others.
A cut-angle sweep (one 2-person scene per angle, 20-180 deg) shows where the fallback takes over.
Speed: cuts + trajectories + shared spaces of a 150-frame 640x360 two-shot clip with moving cameras,
median over ``--runs`` runs, per stage.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

import multithumbs  # noqa: F401  (before numpy and torch: it pins the CPU kernels, multithumbs/cpu_kernels.py)
import numpy as np

from multithumbs.body.model import load_body_model
from multithumbs.geometry import camera_centre
from multithumbs.metrics.alignment import apply_similarity, fit_similarity
from multithumbs.scene import detect_shots, scene_geometry
from multithumbs.scene.two_view import estimate_two_view
from multithumbs.synth.files import write_video
from multithumbs.synth.scene import SceneConfig, synthesize
from multithumbs.synth.suite import suite


def rotation_error_deg(R_a: np.ndarray, R_b: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip((np.trace(R_a.T @ R_b) - 1) / 2, -1, 1))))


def direction_error_deg(a: np.ndarray, b: np.ndarray) -> float:
    na, nb = np.linalg.norm(a), np.linalg.norm(b)
    if na == 0 or nb == 0:
        return float("nan")
    return float(np.degrees(np.arccos(np.clip(np.dot(a, b) / (na * nb), -1, 1))))


def cut_errors(space, world, a: int, b: int) -> tuple[float, float]:
    """Rotation and translation-direction errors (deg) of camera b relative to camera a."""
    R_true = world.R[b] @ world.R[a].T
    t_true = world.t[b] - R_true @ world.t[a]
    R_est = space.R[1] @ space.R[0].T
    t_est = space.t[1] - R_est @ space.t[0]
    return rotation_error_deg(R_est, R_true), direction_error_deg(t_est, t_true)


def ate_percent(traj, world, a: int, b: int) -> tuple[float, float]:
    """ATE RMSE (m) after Sim(3) alignment of the centres, and as a percentage of the trajectory length.

    A straight dolly has collinear centres: the alignment's rotation about the line is then not unique,
    but the least-squares residual (the ATE) is.
    """
    true_c = camera_centre(world.R[a:b], world.t[a:b])
    est_c = camera_centre(traj.R, traj.t)
    sim, _ = fit_similarity(est_c, true_c)
    rmse = float(np.sqrt((np.linalg.norm(apply_similarity(sim, est_c) - true_c, axis=1) ** 2).mean()))
    length = float(np.linalg.norm(np.diff(true_c, axis=0), axis=1).sum())
    return rmse, 100 * rmse / length


def person_masks(video, frame: int) -> np.ndarray:
    return np.stack([video.instance[frame] == p for p in range(video.truth.world.num_people)])


def run_suite(body, names: list[str] | None) -> None:
    configs = [c for c in suite("standard") if not names or c.name in names]
    cut_rows, space_rows, traj_rows = [], [], []
    for config in configs:
        video = synthesize(config, body)
        world = video.truth.world
        truth = world.cut_frames.tolist()
        shots = detect_shots(video.frames, fps=world.fps)
        with tempfile.TemporaryDirectory() as tmp:
            from_file = detect_shots(write_video(Path(tmp) / "video.mp4", video.frames, world.fps))
        false_cuts = len(set(shots.cut_frames.tolist()) - set(truth)) + len(set(from_file.cut_frames.tolist()) - set(truth))
        cut_rows.append((config.name, truth, shots.cut_frames.tolist(), from_file.cut_frames.tolist(), false_cuts))
        for c, cut in enumerate(truth):
            a, b = cut - 1, cut
            start = time.perf_counter()
            result = estimate_two_view(video.frames[a], video.frames[b], np.stack([world.K[a], world.K[b]]),
                                       person_masks(video, a), person_masks(video, b), cut)
            seconds = time.perf_counter() - start
            rot, trans = cut_errors(result.space, world, a, b)
            space_rows.append((config.name, c, config.cut_angle_deg, rotation_error_deg(world.R[a], world.R[b]), rot,
                               trans, result.space.fallback or "-", result.num_inliers, seconds))
        from multithumbs.scene.tracking import track_camera

        for k, (a, b) in enumerate(world.shots().ranges):
            start = time.perf_counter()
            traj = track_camera(video.frames[a:b], world.K[a], video.instance[a:b] >= 0, k, a)
            seconds = time.perf_counter() - start
            moving = config.camera_is_moving(k)
            rmse, pct = ate_percent(traj, world, a, b) if moving and traj.source == "pycolmap" else (float("nan"),) * 2
            traj_rows.append((config.name, k, moving, traj.source, b - a, rmse, pct, seconds))
        print(f"  done {config.name}", flush=True)

    print("\nCUTS (adaptive detector; frames | encoded mp4)")
    exact = 0
    for name, truth, frames, mp4, false_cuts in cut_rows:
        ok = frames == truth and mp4 == truth
        exact += ok
        print(f"  {name:32s} true {truth}  frames {frames}  mp4 {mp4}  false cuts {false_cuts}  {'OK' if ok else 'WRONG'}")
    print(f"  scenes with exactly the true cuts: {exact}/{len(cut_rows)}")

    print("\nSHARED SPACES (pycolmap two-view at each cut, true people masks)")
    print(f"  {'scene':32s} cut  cut-angle  rel-rot  rot-err  t-dir-err  path  inliers  seconds")
    for name, c, angle, rel, rot, trans, path, inliers, sec in space_rows:
        print(f"  {name:32s} {c:3d}  {angle:9.0f}  {rel:7.1f}  {rot:7.3f}  {trans:9.3f}  {path:4s}  {inliers:7d}  {sec:7.1f}")
    small = [r for r in space_rows if r[2] <= 60]
    print(f"  median over {len(small)} cuts with cut angle <= 60 deg: rotation error "
          f"{statistics.median(r[4] for r in small):.3f} deg (target <= 2), translation-direction error "
          f"{statistics.median(r[5] for r in small):.3f} deg (target <= 5)")
    print(f"  median over all {len(space_rows)} cuts: rotation {statistics.median(r[4] for r in space_rows):.3f} deg, "
          f"translation direction {statistics.median(r[5] for r in space_rows):.3f} deg; "
          f"max {max(r[4] for r in space_rows):.3f} / {max(r[5] for r in space_rows):.3f} deg")

    print("\nCAMERA TRAJECTORIES (KLT + pycolmap)")
    for name, k, moving, source, frames, rmse, pct, sec in traj_rows:
        extra = f"ATE {1000 * rmse:.1f} mm = {pct:.2f}% of length" if np.isfinite(pct) else ""
        print(f"  {name:32s} shot {k}  {'moving' if moving else 'static':6s} -> {source:24s} {frames:3d} frames "
              f"{sec:5.1f} s  {extra}")
    moving = [r[6] for r in traj_rows if r[2]]
    if moving:
        print(f"  median ATE of {len(moving)} moving-camera shots: {statistics.median(moving):.2f}% of the trajectory "
              f"length (target <= 2%); max {max(moving):.2f}%")
    wrong_static = [r for r in traj_rows if (not r[2]) != (r[3] == "static")]
    print(f"  static detection wrong in {len(wrong_static)} of {len(traj_rows)} shots")


def run_sweep(body) -> None:
    print("\nCUT-ANGLE SWEEP (2 people, 640x360, seed 5; where does the fallback take over?)")
    print("  cut-angle  rot-err  t-dir-err  path          inliers  matches")
    for angle in (20, 40, 60, 80, 100, 120, 140, 160, 180):
        config = SceneConfig(num_people=2, num_shots=2, num_frames=16, seed=5, cut_angle_deg=angle)
        video = synthesize(config, body)
        world = video.truth.world
        cut = int(world.cut_frames[0])
        result = estimate_two_view(video.frames[cut - 1], video.frames[cut], world.K[cut], person_masks(video, cut - 1),
                                   person_masks(video, cut), cut)
        rot, trans = cut_errors(result.space, world, cut - 1, cut)
        print(f"  {angle:9d}  {rot:7.3f}  {trans:9.3f}  {result.space.fallback or 'two_view':12s}  "
              f"{result.num_inliers:7d}  {result.num_matches:7d}", flush=True)


def run_speed(body, runs: int) -> None:
    config = SceneConfig(num_people=3, num_shots=2, num_frames=150, seed=3, image_size=(360, 640), moving_cameras=True)
    video = synthesize(config, body)
    world = video.truth.world
    totals, stages = [], {"cuts": [], "trajectories": [], "spaces": []}
    with tempfile.TemporaryDirectory() as tmp:
        path = write_video(Path(tmp) / "clip.mp4", video.frames, world.fps)
        for run in range(runs):
            start = time.perf_counter()
            shots = detect_shots(path)
            cut_time = time.perf_counter() - start
            geometry = scene_geometry(video.frames, shots, world.K[0], video.instance >= 0)
            total = time.perf_counter() - start
            totals.append(total)
            stages["cuts"].append(cut_time)
            for key, value in geometry.seconds.items():
                stages[key].append(value)
            print(f"  run {run}: {total:.1f} s (cuts {cut_time:.1f}, trajectories {geometry.seconds['trajectories']:.1f}"
                  f", shared spaces {geometry.seconds['spaces']:.1f}); cuts {shots.cut_frames.tolist()}, "
                  f"trajectories {[t.source for t in geometry.trajectories]}", flush=True)
    medians = {k: statistics.median(v) for k, v in stages.items()}
    print(f"\nSPEED: median {statistics.median(totals):.1f} s for cuts + trajectories + shared spaces of a 150-frame "
          f"640x360 two-shot clip with moving cameras (target <= 30 s); per stage: "
          + ", ".join(f"{k} {v:.1f} s" for k, v in medians.items())
          + f"; dominated by {max(medians, key=medians.get)}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--scenes", type=str, default=None, help="comma-separated standard-suite scenes")
    parser.add_argument("--skip-suite", action="store_true")
    parser.add_argument("--skip-sweep", action="store_true")
    parser.add_argument("--skip-speed", action="store_true")
    args = parser.parse_args()
    body = load_body_model()
    if not args.skip_suite:
        run_suite(body, args.scenes.split(",") if args.scenes else None)
    if not args.skip_sweep:
        run_sweep(body)
    if not args.skip_speed:
        run_speed(body, args.runs)


if __name__ == "__main__":
    main()
