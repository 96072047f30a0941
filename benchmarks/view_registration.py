"""Per-cut accuracy of the view registration (:mod:`multithumbs.method.views`) on the standard suite.

For every cut: the error of the relative pose of the two boundary cameras against the truth, without the
registration (the simulated shared space's cameras) and with it, as the alignment places them before its
stages. Rotation: the angle of ``R1 R0ᵀ`` against the truth's (degrees). Centre: the distance (m) between
camera 1's centre in camera 0's frame and the truth's, the space brought to metres by its true scale (so
the scale estimate's error is not counted; ``centre_after_est_scale``: by the alignment's estimate). Means and medians over cuts.

Usage: python benchmarks/view_registration.py [--scenes s01,s02] [--perturb 1e-12]

``--perturb``: also register with the shared space's points scaled by ``1 + perturb`` (a rounding-level
change) and print how far the registered cameras move (they should move by about as little).
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics
import time

import multithumbs  # noqa: F401  (before numpy and torch: it pins the CPU kernels, multithumbs/cpu_kernels.py)
import numpy as np

from multithumbs.body.model import load_body_model
from multithumbs.determinism import fix_threads
from multithumbs.geometry import camera_centre
from multithumbs.method.align import AlignConfig, align_boundary
from multithumbs.pipeline import boundary_people, sanitize_tracks
from multithumbs.synth.perception import simulate_perception
from multithumbs.synth.scene import synthesize
from multithumbs.synth.simulated_geometry import simulate_shared_space
from multithumbs.synth.suite import suite

NO_STAGES = dict(iterations=(0, 0, 0))
"""The alignment stopped after the registration: its cameras are the registered ones."""


def relative_pose(R: np.ndarray, t: np.ndarray, per_metre: float) -> tuple[np.ndarray, np.ndarray]:
    """Camera 1's rotation ``R1 R0ᵀ`` and its centre (m) in camera 0's frame, for a space of ``per_metre``
    units per metre."""
    C = camera_centre(R, t)
    return R[1] @ R[0].T, R[0] @ (C[1] - C[0]) / per_metre


def true_scale(space, truth_depth: np.ndarray) -> float:
    """The shared space's units per metre: its camera-frame depths over the true depths at the points' pixels."""
    ratios = []
    for k in range(2):
        own = space.observed[k] & ~space.observed[1 - k]
        pts = space.points[own] @ space.R[k].T + space.t[k]
        px = np.round(space.pixels[k, own]).astype(int)
        ratios.append(pts[:, 2] / truth_depth[k][px[:, 1], px[:, 0]])
    return float(np.median(np.concatenate(ratios)))


def difference(a: tuple[np.ndarray, np.ndarray], b: tuple[np.ndarray, np.ndarray]) -> tuple[float, float]:
    """Rotation angle (degrees) and centre distance (m) between two relative poses."""
    m = a[0].T @ b[0]
    sin = 0.5 * np.linalg.norm([m[2, 1] - m[1, 2], m[0, 2] - m[2, 0], m[1, 0] - m[0, 1]])
    angle = np.arctan2(sin, (np.trace(m) - 1) / 2)   # accurate near 0, where arccos of the trace is not
    return float(np.degrees(angle)), float(np.linalg.norm(a[1] - b[1]))


def registered_pose(people, space, per_metre: float | None) -> tuple[np.ndarray, np.ndarray]:
    """The relative pose the alignment starts its stages from (the registered cameras); ``per_metre``
    None: in the alignment's own metres (its scale estimate)."""
    aligned = align_boundary(people, space, AlignConfig(**NO_STAGES))
    if per_metre is None:
        return relative_pose(aligned.R, aligned.t, 1.0)
    s = aligned.scale if np.isfinite(aligned.scale) and aligned.scale > 0 else 1.0
    return relative_pose(aligned.R, aligned.t, per_metre * s)  # the alignment rescaled the space by s


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--scenes", default="", help="comma-separated scene names (default: all)")
    parser.add_argument("--perturb", type=float, default=0.0)
    args = parser.parse_args()
    fix_threads()
    body = load_body_model()
    wanted = set(filter(None, args.scenes.split(",")))
    rows = []
    start = time.perf_counter()
    for config in suite("standard"):
        if wanted and config.name not in wanted:
            continue
        video = synthesize(config, body)
        world = video.truth.world
        tracks = [sanitize_tracks(t) for t in simulate_perception(video, body)]
        for c, cut in enumerate(world.cut_frames):
            space = simulate_shared_space(video, c)
            people = boundary_people(tracks[c], tracks[c + 1], body, K=space.K)
            frames = [int(cut) - 1, int(cut)]
            per_metre = true_scale(space, video.boundary_depth[c])
            truth = relative_pose(world.R[frames], world.t[frames], 1.0)
            before = difference(relative_pose(space.R, space.t, per_metre), truth)
            registered = registered_pose(people, space, per_metre)
            after = difference(registered, truth)
            estimated = difference(registered_pose(people, space, None), truth)[1]
            row = {"cut": f"{config.name} cut {c}", "rot_before": before[0], "centre_before": before[1],
                   "rot_after": after[0], "centre_after": after[1], "centre_after_est_scale": estimated}
            if args.perturb:
                nudged = dataclasses.replace(space, points=space.points * (1 + args.perturb))
                row["moved_rot"], row["moved_centre"] = difference(registered_pose(people, nudged, per_metre),
                                                                   registered)
            rows.append(row)
            extra = f"  moved {row['moved_rot']:.2e} deg {row['moved_centre']:.2e} m" if args.perturb else ""
            print(f"{row['cut']:>12}: rotation {before[0]:.2f} -> {after[0]:.2f} deg, "
                  f"centre {before[1]:.3f} -> {after[1]:.3f} m{extra}", flush=True)
    for name in ("rot_before", "rot_after", "centre_before", "centre_after", "centre_after_est_scale"):
        values = [r[name] for r in rows]
        print(f"{name:>14}: mean {statistics.mean(values):.3f} median {statistics.median(values):.3f} "
              f"max {max(values):.3f} over {len(values)} cuts")
    if args.perturb:
        print(f"largest change from a {args.perturb:g} relative perturbation: "
              f"{max(r['moved_rot'] for r in rows):.2e} deg, {max(r['moved_centre'] for r in rows):.2e} m")
    print(f"{time.perf_counter() - start:.0f} s")


if __name__ == "__main__":
    main()
