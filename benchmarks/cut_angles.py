"""W-MPJPE, identity switches and the boundary cameras' rotation error against the cut angle, 20-180 degrees.

Two layouts of two people: ``orbit`` (the standard suite's: people walking, cameras about the room's centre
looking in, which share the middle of the floor even at 180 degrees) and ``dialogue`` (shot/reverse-shot
over the shoulder, :mod:`multithumbs.synth.dialogue`: the boundary frames share no background). Perception
is SIMULATED (the bench's); the scene geometry is either SIMULATED (``--geometry simulated``: the VGGT
stand-in, which falls back when the frames share < 5 % of the room) or FROM PIXELS (``pixels``: pycolmap
camera tracking and two-view shared space on the rendered frames, people masked by the simulated masks,
true cuts and intrinsics). Each scene runs the full method twice: with the people-based cameras where the
space fell back (the default) and without them (``people_cameras="never"``).

Per scene: W-MPJPE (mm), IDs (switches), rotation error (degrees) of the boundary cameras' relative
rotation ``R_b R_{b-1}^T`` against the truth's, and where the cameras came from (scene / people / none).
Writes a JSON and a plot (``--plot``: W-MPJPE and rotation error against the angle, fallback cuts marked).

    .venv/bin/python benchmarks/cut_angles.py [--geometry simulated|pixels] [--workers 2] [--json OUT]
        [--plot docs/cut_angles.png] [--suite dialogue]

``--suite NAME``: the same figures for a suite's scenes (every cut) instead of the sweep.
"""

from __future__ import annotations

import argparse
import json
import time
from concurrent.futures import ProcessPoolExecutor

ORBIT_ANGLES = (20, 45, 75, 90, 120, 150, 180)
DIALOGUE_ANGLES = (60, 90, 120, 150, 180)


def scene_config(layout: str, angle: int):
    from multithumbs.synth.scene import SceneConfig
    from multithumbs.synth.suite import SUITES

    for configs in SUITES.values():  # a suite's scene, by name
        for config in configs:
            if config.name == layout:
                return config
    if layout == "orbit":
        return SceneConfig(name=f"orbit_{angle}deg", num_people=2, num_shots=2, cut_angle_deg=angle, seed=400 + angle)
    return SceneConfig(name=f"dialogue_{angle}deg", num_people=2, num_shots=2, cut_angle_deg=angle, seed=500 + angle,
                       dialogue=True, camera_distance=2.0, camera_height=(1.45, 1.65))


def cut_rotation_error(result, truth) -> list[float]:
    """Degrees between the result's and the truth's relative rotation of each cut's boundary cameras."""
    import numpy as np

    from multithumbs.geometry import rotation_angle

    out = []
    for cut in truth.world.cut_frames:
        rel = [w.R[cut] @ w.R[cut - 1].T for w in (result, truth.world)]
        out.append(float(np.rad2deg(rotation_angle(rel[0], rel[1]))))
    return out


def run_one(job: tuple[str, int, str]) -> dict:
    import dataclasses

    import torch

    torch.set_num_threads(1)
    from multithumbs.body.model import load_body_model
    from multithumbs.determinism import fix_threads
    from multithumbs.metrics.evaluate import evaluate
    from multithumbs.pipeline import CAMERAS_FROM, MethodConfig, run_video
    from multithumbs.synth.perception import simulate_perception
    from multithumbs.synth.scene import synthesize
    from multithumbs.synth.simulated_geometry import simulate_camera_trajectory, simulate_shared_space

    layout, angle, geometry = job
    fix_threads()
    body = load_body_model()
    video = synthesize(scene_config(layout, angle), body)
    shots = video.truth.world.shots()
    tracks = simulate_perception(video, body)
    if geometry == "pixels":
        import numpy as np

        from multithumbs.scene.geometry import scene_geometry

        found = scene_geometry(video.frames, shots, video.truth.world.K, np.concatenate([tr.people_mask() for tr in tracks]))
        trajectories, spaces = list(found.trajectories), list(found.spaces)
    else:
        trajectories = [simulate_camera_trajectory(video, k) for k in range(shots.num_shots)]
        spaces = [simulate_shared_space(video, c) for c in range(shots.num_shots - 1)]
    out = {"layout": layout, "angle": angle, "geometry": geometry,
           "fallback": [s.fallback for s in spaces]}
    for name, mode in (("people", "fallback"), ("never", "never")):
        base = MethodConfig()
        config = dataclasses.replace(base, align=dataclasses.replace(base.align, people_cameras=mode))
        result = run_video(shots, tracks, trajectories, spaces, body, config)
        scores = evaluate(result, video.truth, body)
        out[name] = {"w_mpjpe": float(scores["w_mpjpe"]), "ids": float(scores["ids"]),
                     "rotation_error_deg": cut_rotation_error(result, video.truth),
                     "cameras_from": [CAMERAS_FROM[int(result.diagnostics[f"cameras_from_cut{c}"])]
                                      for c in range(len(spaces))]}
    return out


def plot(rows: list[dict], path: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.4))
    styles = {("orbit", "people"): ("tab:blue", "-o"), ("dialogue", "people"): ("tab:red", "-o"),
              ("orbit", "never"): ("tab:blue", ":x"), ("dialogue", "never"): ("tab:red", ":x")}
    for (layout, run), (colour, style) in styles.items():
        sel = sorted((r for r in rows if r["layout"] == layout), key=lambda r: r["angle"])
        if not sel:
            continue
        angles = [r["angle"] for r in sel]
        label = f"{layout}, {'people cameras at fallbacks' if run == 'people' else 'no people cameras'}"
        axes[0].plot(angles, [r[run]["w_mpjpe"] for r in sel], style, color=colour, label=label)
        axes[1].plot(angles, [max(r[run]["rotation_error_deg"][0], 1e-3) for r in sel], style, color=colour, label=label)
        for r in sel:  # the cuts whose space fell back: a ring
            if r["fallback"][0]:
                axes[0].plot(r["angle"], r[run]["w_mpjpe"], "o", ms=13, mfc="none", color="black")
                axes[1].plot(r["angle"], max(r[run]["rotation_error_deg"][0], 1e-3), "o", ms=13, mfc="none",
                             color="black")
    axes[0].set(xlabel="cut angle (degrees)", ylabel="W-MPJPE (mm)", yscale="log",
                title="W-MPJPE (rings: the shared space fell back)")
    axes[1].set(xlabel="cut angle (degrees)", ylabel="rotation error at the cut (degrees)", yscale="log",
                title="boundary cameras' relative rotation error")
    axes[1].axhline(5.0, color="grey", lw=0.8, ls="--")
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=4, fontsize=8, frameon=False)
    fig.tight_layout(rect=(0, 0.07, 1, 1))
    fig.savefig(path, dpi=110)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--geometry", choices=("simulated", "pixels"), default="simulated")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--json", default="")
    parser.add_argument("--plot", default="")
    parser.add_argument("--suite", default="", help="the scenes of this suite instead of the sweep")
    args = parser.parse_args()
    jobs = [("orbit", a, args.geometry) for a in ORBIT_ANGLES] + [("dialogue", a, args.geometry)
                                                                   for a in DIALOGUE_ANGLES]
    if args.suite:
        from multithumbs.synth.suite import suite

        jobs = [(c.name, int(c.cut_angle_deg), args.geometry) for c in suite(args.suite)]
    start = time.perf_counter()
    with ProcessPoolExecutor(args.workers) as pool:
        rows = list(pool.map(run_one, jobs))
    wall = time.perf_counter() - start
    print(f"geometry {args.geometry}; perception SIMULATED; {len(rows)} scenes in {wall:.0f} s")
    print(f"{'scene':<14}{'fallback':<9}{'W-MPJPE':>9}{'(never)':>9}{'IDs':>5}{'rot°':>7}{'(never)':>9}  cameras")
    for r in rows:
        p, n = r["people"], r["never"]
        for c in range(len(r["fallback"])):  # one line per cut
            first = c == 0
            print(f"{(r['layout'][:8] + ' ' + str(r['angle'])) if first else '  cut ' + str(c):<14}"
                  f"{'yes' if r['fallback'][c] else '-':<9}"
                  + (f"{p['w_mpjpe']:>9.1f}{n['w_mpjpe']:>9.1f}{p['ids']:>5.0f}" if first else " " * 23)
                  + f"{p['rotation_error_deg'][c]:>7.2f}{n['rotation_error_deg'][c]:>9.2f}  {p['cameras_from'][c]}")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({"geometry": args.geometry, "wall_seconds": wall, "rows": rows}, fh, indent=1)
    if args.plot:
        plot(rows, args.plot)


if __name__ == "__main__":
    main()
