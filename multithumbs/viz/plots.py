"""Static pictures with matplotlib (Agg backend, no display): the top-down trajectory plot and benchmark plots.

Top-down: the world is turned so that its estimated up direction is +z (:func:`multithumbs.export.posed.
world_up`) and seen from above. Every person's pelvis path is drawn in its id colour, one line per shot
(cuts are not drawn as motion), with a marker where each shot starts; every shot's camera centres in
grey with the viewing direction at the shot's first frame; a red cross marks every person and camera
position at each cut. With ground truth, the truth is drawn dashed in the same axes: the result is
mapped onto the truth's world by one Sim(3) (Umeyama) fitted to the camera centres of all frames and the
pelvis paths of people paired by the evaluation's pairing (:func:`multithumbs.viz.pairing.pair_with_truth`;
a display alignment, like the metrics' world alignment), and the plot is in the truth's frame. Each
result person is then drawn in the colour of its paired truth person (:mod:`multithumbs.viz.pairing`), so
a correct result lies on dashed lines of its own colour and an identity switch at a cut shows as the
solid line changing colour along one dashed path.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from multithumbs.errors import InputError
from multithumbs.export.files import atomic_output
from multithumbs.export.posed import camera_centres, rotation_to_z_up, shot_index, world_up
from multithumbs.metrics.alignment import apply_similarity, fit_similarity
from multithumbs.types import GroundTruth, WorldResult
from multithumbs.viz.pairing import TruthColouring, colouring_for, pair_with_truth
from multithumbs.viz.palette import id_color


def _pyplot():
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    return plt


def save_figure(figure, paths: list[Path], dpi: int = 130) -> list[Path]:
    """Save a matplotlib figure to each path (format from the suffix: png, svg, pdf) atomically, then close it."""
    plt = _pyplot()
    try:
        for path in paths:
            with atomic_output(path) as tmp:
                figure.savefig(tmp, dpi=dpi, bbox_inches="tight", format=Path(path).suffix.lstrip("."))
    finally:
        plt.close(figure)
    return [Path(p) for p in paths]


def result_to_truth(result: WorldResult, joints: np.ndarray, truth: GroundTruth, true_joints: np.ndarray):
    """The display Sim(3) mapping the result's world onto the truth's (module docstring), or None if unfittable.

    Args:
        joints: ``(P, T, 24, 3)`` result world joints; ``true_joints`` ``(G, T, 24, 3)`` the truth's.
    """
    tw = truth.world
    if tw.num_frames != result.num_frames:
        raise InputError(f"truth: {tw.num_frames} frames, but the result has {result.num_frames}")
    src, dst = [camera_centres(result)], [camera_centres(tw)]
    if result.num_people and tw.num_people:
        # The evaluation's pairing: camera-frame pelvis, independent of the world frame.
        pairs = pair_with_truth(result, joints, truth, true_joints)
        for g, p in enumerate(pairs.pred_index):
            if p >= 0:
                both = result.valid[p] & tw.valid[g]
                src.append(joints[p, both, 0])
                dst.append(true_joints[g, both, 0])
    src_pts, dst_pts = np.concatenate(src), np.concatenate(dst)
    if len(src_pts) < 3 or np.linalg.matrix_rank(src_pts - src_pts.mean(0), tol=1e-6) < 2:
        return None
    sim, fitted = fit_similarity(src_pts, dst_pts)
    return sim if bool(fitted) else None


def _top_down_world(world: WorldResult, joints: np.ndarray, rotation: np.ndarray, style: str, ax, label: str,
                    colouring: TruthColouring | None = None) -> None:
    shots = shot_index(world)
    centres = camera_centres(world) @ rotation.T
    pelvis = joints[:, :, 0] @ rotation.T
    cuts = np.asarray(world.cut_frames)
    for p in range(world.num_people):
        colour = id_color(int(world.person_ids[p])) if colouring is None else colouring.colors[p]
        name = f"{label} #{int(world.person_ids[p])}"
        if colouring is not None and colouring.legend:
            partner = int(colouring.partner[p])
            name += f" (paired: truth #{partner})" if partner >= 0 else " (unpaired)"
        first = True
        for s in range(cuts.size + 1):
            frames = np.nonzero((shots == s) & world.valid[p])[0]
            if frames.size == 0:
                continue
            ax.plot(pelvis[p, frames, 0], pelvis[p, frames, 1], style, color=colour, lw=1.6 if style == "-" else 1.2,
                    label=name if first else None)
            ax.plot(pelvis[p, frames[0], 0], pelvis[p, frames[0], 1], "o", color=colour, ms=4,
                    mfc="white" if style != "-" else colour)
            first = False
        at_cut = [c for c in cuts if world.valid[p, c]]
        if at_cut:
            ax.plot(pelvis[p, at_cut, 0], pelvis[p, at_cut, 1], "x", color="red", ms=7, mew=1.5)
    look = (world.R[:, 2, :]) @ rotation.T  # camera +z (viewing direction) in the plot frame
    for s in range(cuts.size + 1):
        frames = np.nonzero(shots == s)[0]
        c = centres[frames]
        ax.plot(c[:, 0], c[:, 1], style, color="0.35", lw=1.2, label=f"{label} cameras" if s == 0 else None)
        f0 = frames[0]
        d = look[f0, :2]
        norm = np.linalg.norm(d)
        if norm > 1e-9:
            d = 0.5 * d / norm
            ax.annotate("", xy=(centres[f0, 0] + d[0], centres[f0, 1] + d[1]), xytext=(centres[f0, 0], centres[f0, 1]),
                        arrowprops=dict(arrowstyle="->", color="0.25", ls="--" if style != "-" else "-"))
        ax.plot(centres[f0, 0], centres[f0, 1], "s", color="0.25", ms=5, mfc="white" if style != "-" else "0.25")
        if style == "-":
            ax.annotate(f"shot {s}", (centres[f0, 0], centres[f0, 1]), textcoords="offset points", xytext=(5, 5),
                        fontsize=8, color="0.2")
    for c in cuts:
        for f in (c - 1, c):
            ax.plot(centres[f, 0], centres[f, 1], "x", color="red", ms=7, mew=1.5)


def trajectory_figure(result: WorldResult, joints: np.ndarray, truth: GroundTruth | None = None,
                      true_joints: np.ndarray | None = None, title: str = "",
                      colouring: TruthColouring | None = None):
    """The top-down figure (module docstring).

    Args:
        result: the reconstruction.
        joints: ``(P, T, 24, 3)`` its world joints (:func:`multithumbs.export.posed.posed_joints`).
        truth: optional ground truth; ``true_joints`` ``(G, T, 24, 3)`` its joints (needed with it).
        title: figure title.
        colouring: the result's colours (default :func:`multithumbs.viz.pairing.colouring_for`: by the
            paired truth person with truth, by the result's ids without).
    Returns:
        a matplotlib figure (close it, or pass it to :func:`save_figure`).
    """
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(7.5, 6.5))
    note = ""
    if truth is not None:
        if true_joints is None:
            raise InputError("true_joints: required with truth")
        if colouring is None:
            colouring = colouring_for(result, joints, truth, true_joints)
        rotation = rotation_to_z_up(world_up(truth.world, true_joints))
        sim = result_to_truth(result, joints, truth, true_joints)
        if sim is None:
            note = " (result not aligned: too few points to fit)"
            rotation_pred = rotation_to_z_up(world_up(result, joints))
            shown_joints, shown_world = joints, result
        else:
            moved = apply_similarity(sim, joints.reshape(-1, 3)).reshape(joints.shape)
            R_new = result.R @ sim.rotation.detach().cpu().numpy().T
            C_new = apply_similarity(sim, camera_centres(result))
            t_new = -np.einsum("tij,tj->ti", R_new, C_new)
            shown_world = WorldResult(result.person_ids, result.global_orient, result.body_pose, result.betas,
                                      result.transl, result.valid, result.K, R_new, t_new, result.cut_frames,
                                      result.fps, result.image_size, result.id_map)
            shown_joints, rotation_pred = moved, rotation
            note = " (result Sim(3)-aligned to the truth for display)"
        _top_down_world(truth.world, true_joints, rotation, "--", ax, "truth")
        _top_down_world(shown_world, shown_joints, rotation_pred, "-", ax, "result", colouring)
        note += f"\n{colouring.legend} (solid: result, dashed: truth)" if colouring.legend else ""
    else:
        rotation = rotation_to_z_up(world_up(result, joints))
        _top_down_world(result, joints, rotation, "-", ax, "result", colouring)
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, alpha=0.3)
    ax.set_xlabel("x (m, up-aligned world)")
    ax.set_ylabel("y (m)")
    cuts = ", ".join(str(int(c)) for c in result.cut_frames) or "none"
    ax.set_title((title + "\n" if title else "") + f"top-down: people and cameras; cuts at frames {cuts} (x){note}",
                 fontsize=9)
    ax.legend(fontsize=7, loc="best", ncol=2)
    return fig


def write_trajectory_plot(out_base: str | Path, result: WorldResult, joints: np.ndarray,
                          truth: GroundTruth | None = None, true_joints: np.ndarray | None = None,
                          title: str = "", colouring: TruthColouring | None = None) -> dict[str, Path]:
    """Write ``<out_base>.png`` and ``<out_base>.svg`` of :func:`trajectory_figure`; returns ``{"png": .., "svg": ..}``."""
    base = Path(out_base)
    fig = trajectory_figure(result, joints, truth, true_joints, title, colouring)
    png, svg = save_figure(fig, [base.with_suffix(".png"), base.with_suffix(".svg")])
    return {"png": png, "svg": svg}


def benchmark_table(summary: Mapping[str, Any]) -> tuple[list[str], list[str], dict[str, dict[str, dict[str, float]]]]:
    """Read ``multithumbs bench --json`` output: variant -> metric -> ``{"per_scene": {scene: v}, "mean": v}``.

    Keys starting with ``_`` (``_meta``) are skipped; ``None`` values (NaN in JSON) become NaN.
    Returns:
        variants, metrics (in first-seen order) and ``values[metric][variant][scene]``.
    """
    if not isinstance(summary, Mapping):
        raise InputError("benchmark summary: expected a JSON object keyed by variant")
    variants, metrics = [], []
    values: dict[str, dict[str, dict[str, float]]] = {}
    for variant, per_metric in summary.items():
        if str(variant).startswith("_"):
            continue
        if not isinstance(per_metric, Mapping):
            raise InputError(f"benchmark summary[{variant!r}]: expected an object keyed by metric")
        variants.append(str(variant))
        for metric, entry in per_metric.items():
            if not isinstance(entry, Mapping) or "per_scene" not in entry:
                raise InputError(f"benchmark summary[{variant!r}][{metric!r}]: expected {{'per_scene': ..., 'mean': ...}}")
            if metric not in values:
                metrics.append(str(metric))
                values[metric] = {}
            values[metric][variant] = {str(s): (math.nan if v is None else float(v))
                                       for s, v in entry["per_scene"].items()}
    if not variants:
        raise InputError("benchmark summary: no variant in it")
    return variants, metrics, values


def benchmark_figure(summary: Mapping[str, Any], metric: str):
    """Grouped bars of one metric: scenes along x, one bar per variant, plus each variant's mean."""
    plt = _pyplot()
    variants, metrics, values = benchmark_table(summary)
    if metric not in values:
        raise InputError(f"metric {metric!r}: not in the benchmark summary ({', '.join(metrics)})")
    per_variant = values[metric]
    scenes = sorted({s for v in per_variant.values() for s in v})
    shown = [v for v in variants if v in per_variant]
    fig, ax = plt.subplots(figsize=(max(6.0, 0.9 * (len(scenes) + 1) * max(1, len(shown)) ** 0.5 + 2), 4.2))
    width = 0.8 / max(len(shown), 1)
    x = np.arange(len(scenes) + 1)
    for i, variant in enumerate(shown):
        vals = [per_variant[variant].get(s, math.nan) for s in scenes]
        finite = [v for v in vals if np.isfinite(v)]
        vals.append(float(np.mean(finite)) if finite else math.nan)
        ax.bar(x + (i - (len(shown) - 1) / 2) * width, vals, width, label=variant,
               color=id_color(i), edgecolor="black", linewidth=0.3)
    ax.set_xticks(x, [*scenes, "mean"], rotation=35, ha="right", fontsize=7)
    ax.set_ylabel(metric)
    ax.set_title(f"{metric} per scene and variant", fontsize=10)
    ax.grid(True, axis="y", alpha=0.3)
    ax.legend(fontsize=7, ncol=min(4, len(shown)))
    return fig


def write_benchmark_plots(out_dir: str | Path, summary: Mapping[str, Any], metrics: list[str] | None = None,
                          formats: tuple[str, ...] = ("png", "svg")) -> dict[str, Path]:
    """One figure per metric (:func:`benchmark_figure`) as ``bench_<metric>.<format>`` in ``out_dir``.

    Returns:
        ``"<metric>.<format>"`` -> path.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    _, all_metrics, _ = benchmark_table(summary)
    written: dict[str, Path] = {}
    for metric in metrics or all_metrics:
        safe = "".join(ch if ch.isalnum() or ch in "-_" else "_" for ch in metric)
        paths = [out / f"bench_{safe}.{fmt}" for fmt in formats]
        for fmt, path in zip(formats, save_figure(benchmark_figure(summary, metric), paths)):
            written[f"{metric}.{fmt}"] = path
    return written
