"""Every picture and export of one video, in one call: :func:`write_video_outputs`.

Layout of ``out_dir`` (kinds in brackets; pass ``include`` to write a subset):

- ``overlay.mp4`` [overlay]: meshes over the input frames (:mod:`multithumbs.viz.overlay`).
- ``trajectory.png``, ``trajectory.svg`` [trajectory]: top-down plot (:mod:`multithumbs.viz.plots`).
- ``smpl/person_<id>.npz`` [smpl]: world SMPL parameters per person (:mod:`multithumbs.export.smpl`).
- ``cameras.npz`` [cameras] and ``colmap/{cameras,images,points3D}.txt`` [colmap] (:mod:`multithumbs.export.cameras`).
- ``bvh/person_<id>.bvh`` [bvh]: SMPL skeleton motion per person (:mod:`multithumbs.export.bvh`).
- ``scene.glb`` [glb]: animated glTF of the sequence (:mod:`multithumbs.export.glb`).
- ``scene.rrd`` [rrd]: rerun recording (:mod:`multithumbs.export.rrd`).
- ``report.md`` [report]: the report (:mod:`multithumbs.viz.report`).
- ``outputs.json``: the manifest of what this function wrote (always).

Every file is written to a temporary name and renamed into place. Existing files are replaced only if
the folder's manifest says this function wrote them, or with ``overwrite=True``; the check runs before
anything is written, so a refusal leaves the folder untouched. Once the check passes, the manifest is
written first (``"complete": false``) listing every planned file, and rewritten at the end with what was
written: a run that fails part-way can be retried (a Prefect task retry, or the same command again)
and replaces its own partial output instead of refusing it.
"""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from multithumbs.errors import InputError
from multithumbs.io import make_output_dir
from multithumbs.export.files import write_text_atomic
from multithumbs.export.smpl import person_file_name
from multithumbs.types import GroundTruth, WorldResult

OUTPUT_KINDS = ("overlay", "trajectory", "smpl", "cameras", "colmap", "bvh", "glb", "rrd", "report")
MANIFEST_NAME = "outputs.json"
MANIFEST_FORMAT = "multithumbs.outputs/1"


def planned_files(result: WorldResult, include: Sequence[str] = OUTPUT_KINDS) -> dict[str, str]:
    """Output key -> path relative to the output folder of everything :func:`write_video_outputs` writes."""
    unknown = sorted(set(include) - set(OUTPUT_KINDS))
    if unknown:
        raise InputError(f"include: unknown output kind {unknown[0]!r} (known: {', '.join(OUTPUT_KINDS)})")
    plan: dict[str, str] = {}
    ever_valid = [int(g) for g, v in zip(result.person_ids, result.valid.any(axis=1)) if v]
    if "overlay" in include:
        plan["overlay"] = "overlay.mp4"
    if "trajectory" in include:
        plan.update(trajectory_png="trajectory.png", trajectory_svg="trajectory.svg")
    if "smpl" in include:
        plan.update({f"smpl/{person_file_name(g, '')}": f"smpl/{person_file_name(g, '.npz')}"
                     for g in result.person_ids})
    if "cameras" in include:
        plan["cameras"] = "cameras.npz"
    if "colmap" in include:
        plan.update({f"colmap/{n}": f"colmap/{n}" for n in ("cameras.txt", "images.txt", "points3D.txt")})
    if "bvh" in include:
        plan.update({f"bvh/{person_file_name(g, '')}": f"bvh/{person_file_name(g, '.bvh')}" for g in ever_valid})
    if "glb" in include:
        plan["glb"] = "scene.glb"
    if "rrd" in include:
        plan["rrd"] = "scene.rrd"
    if "report" in include:
        plan["report"] = "report.md"
    plan["manifest"] = MANIFEST_NAME
    return plan


def _read_manifest(out: Path) -> set[str] | None:
    """Files an earlier export's manifest lists; None when there is no manifest or it is not ours."""
    path = out / MANIFEST_NAME
    if not path.is_file():
        return None
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(data, dict) or data.get("format") != MANIFEST_FORMAT:
        return None
    return {str(f) for f in data.get("files", [])}


def check_output_dir(out_dir: str | Path, plan: Mapping[str, str], overwrite: bool = False) -> Path:
    """Create ``out_dir`` and refuse to replace files this module did not write (module docstring)."""
    out = make_output_dir(out_dir)
    if overwrite:
        return out
    ours = _read_manifest(out)
    for rel in plan.values():
        if (out / rel).exists() and (ours is None or rel not in ours | {MANIFEST_NAME}):
            raise InputError(f"{out / rel}: already exists and was not written by an earlier export "
                             f"(pass --overwrite / overwrite=True to replace it)")
    return out


def _point_colors(video_path: Path, result: WorldResult, points: list[np.ndarray]) -> list[np.ndarray] | None:
    """RGB of each cut's scene points sampled in the cut's first frame (grey where they do not project)."""
    from multithumbs.export.cameras import project_to_frame
    from multithumbs.video import read_frames

    if not points:
        return None
    cuts = [int(c) for c in result.cut_frames]
    frames = read_frames(video_path, cuts)
    colours = []
    for frame, cut, pts in zip(frames, cuts, points):
        uv, inside = project_to_frame(result, cut, pts)
        col = np.full((len(pts), 3), 128, np.uint8)
        px = np.round(uv[inside]).astype(int)
        h, w = frame.shape[:2]
        px[:, 0], px[:, 1] = px[:, 0].clip(0, w - 1), px[:, 1].clip(0, h - 1)
        col[inside] = frame[px[:, 1], px[:, 0]]
        colours.append(col)
    return colours


def write_video_outputs(out_dir: str | Path, result: WorldResult, video_path: str | Path,
                        truth: GroundTruth | None = None, metrics: Mapping[str, Any] | None = None,
                        run_info: Mapping[str, Any] | None = None,
                        scene_points: Sequence[np.ndarray] | None = None, body=None, *,
                        include: Sequence[str] = OUTPUT_KINDS, overwrite: bool = False, glb_stride: int = 1,
                        bvh_scale: float = 1.0, title: str | None = None,
                        progress: Callable[[str], None] | None = None) -> dict[str, Path]:
    """Write the pictures, exports and report of one video (module docstring).

    Args:
        out_dir: output folder (created if missing).
        result: the reconstruction.
        video_path: the input video (its frames are the result's frames).
        truth: optional ground truth (truth panel in the overlay, dashed truth in the top-down plot; the
            result is then coloured by the paired truth person, :mod:`multithumbs.viz.pairing`).
        metrics: optional metrics for the report (e.g. :func:`multithumbs.metrics.evaluate.evaluate`).
        run_info: optional backends, fallbacks and stage timings for the report (:mod:`multithumbs.viz.report`).
        scene_points: optional scene points of each cut in the WORLD frame (``SharedSpace.points`` mapped
            through the shot's placement), one ``(N, 3)`` array per cut; go into the GLB, the rerun
            recording and COLMAP's ``points3D.txt``.
        body: the body model (default: :func:`multithumbs.body.model.load_body_model`).
        include: output kinds to write (:data:`OUTPUT_KINDS`).
        overwrite: replace existing files this function did not write.
        glb_stride: export every n-th frame to the GLB.
        bvh_scale: BVH length unit factor (1 = metres, 100 = centimetres).
        title: report title (default: the video's name).
        progress: optional callable told the name of each output as it starts.
    Returns:
        output key -> path of every file written (keys of :func:`planned_files`).
    """
    from multithumbs.export.bvh import write_bvh
    from multithumbs.export.cameras import check_scene_points, write_cameras_npz, write_colmap_text
    from multithumbs.export.posed import posed_joints, posed_people, rotation_to_y_up, rotation_to_z_up, world_up
    from multithumbs.export.smpl import write_smpl_npz
    from multithumbs.viz.report import render_report_markdown

    video_path = Path(video_path)
    if not video_path.is_file():
        raise InputError(f"{video_path}: no such video file")
    if truth is not None and truth.world.num_frames != result.num_frames:
        raise InputError(f"truth: {truth.world.num_frames} frames, but the result has {result.num_frames}")
    points = check_scene_points(scene_points, int(result.cut_frames.size))
    include = tuple(include)
    plan = planned_files(result, include)
    out = check_output_dir(out_dir, plan, overwrite)
    earlier = _read_manifest(out) or set()
    # Claim the planned files before writing any (module docstring: retries after a partial write).
    _write_manifest(out, video_path, earlier | set(plan.values()), {}, complete=False)
    if body is None:
        from multithumbs.body.model import load_body_model

        body = load_body_model()
    written: dict[str, Path] = {}
    timings: dict[str, float] = {}

    def stage(name: str):
        if progress is not None:
            progress(name)
        return time.perf_counter()

    start = stage("posing")
    needs_mesh = {"glb", "rrd"} & set(include)
    if needs_mesh:
        vertices, joints = posed_people(result, body)
    else:
        vertices, joints = None, posed_joints(result, body)
    up = world_up(result, joints)
    true_joints = colouring = None
    if truth is not None and {"overlay", "trajectory"} & set(include):
        from multithumbs.viz.pairing import colouring_for

        # One pairing for every picture: the overlay and the plot colour each person alike.
        true_joints = posed_joints(truth.world, body)
        colouring = colouring_for(result, joints, truth, true_joints)
    timings["posing"] = time.perf_counter() - start

    if "overlay" in include:
        start = stage("overlay")
        from multithumbs.viz.overlay import write_overlay_video

        written["overlay"] = write_overlay_video(out / plan["overlay"], result, video_path, body, truth,
                                                 colouring=colouring)
        timings["overlay"] = time.perf_counter() - start
    if "trajectory" in include:
        start = stage("trajectory")
        from multithumbs.viz.plots import write_trajectory_plot

        pics = write_trajectory_plot(out / "trajectory", result, joints, truth, true_joints,
                                     title=title or video_path.name, colouring=colouring)
        written.update(trajectory_png=pics["png"], trajectory_svg=pics["svg"])
        timings["trajectory"] = time.perf_counter() - start
    if "smpl" in include:
        start = stage("smpl")
        (out / "smpl").mkdir(exist_ok=True)
        for p, gid in enumerate(result.person_ids):
            key = f"smpl/{person_file_name(gid, '')}"
            written[key] = write_smpl_npz(out / plan[key], result, p, joints[p], up, getattr(body, "source", "unknown"))
        timings["smpl"] = time.perf_counter() - start
    if "cameras" in include:
        start = stage("cameras")
        written["cameras"] = write_cameras_npz(out / plan["cameras"], result, up)
        timings["cameras"] = time.perf_counter() - start
    if "colmap" in include:
        start = stage("colmap")
        colmap = write_colmap_text(out / "colmap", result, points, _point_colors(video_path, result, points))
        written.update({f"colmap/{n}": p for n, p in colmap.items()})
        timings["colmap"] = time.perf_counter() - start
    if "bvh" in include:
        start = stage("bvh")
        (out / "bvh").mkdir(exist_ok=True)
        to_y = rotation_to_y_up(up)
        for p, gid in enumerate(result.person_ids):
            key = f"bvh/{person_file_name(gid, '')}"
            if key in plan:
                written[key] = write_bvh(out / plan[key], result, p, body, joints[p], to_y, bvh_scale)
        timings["bvh"] = time.perf_counter() - start
    if "glb" in include:
        start = stage("glb")
        from multithumbs.export.glb import write_glb

        written["glb"] = write_glb(out / plan["glb"], result, vertices, body.faces, rotation_to_y_up(up), points,
                                   glb_stride)
        timings["glb"] = time.perf_counter() - start
    if "rrd" in include:
        start = stage("rrd")
        from multithumbs.export.rrd import write_rrd
        from multithumbs.video import iter_frames

        written["rrd"] = write_rrd(out / plan["rrd"], result, vertices, joints, body.faces, rotation_to_z_up(up),
                                   points, iter_frames(video_path, 0, result.num_frames))
        timings["rrd"] = time.perf_counter() - start
    if "report" in include:
        stage("report")
        info = dict(run_info or {})
        info["export_timings"] = {**dict(info.get("export_timings") or {}), **timings}
        text = render_report_markdown(result, {**written, "report": out / plan["report"]}, metrics, info,
                                      title=title or f"Multi-THuMBS: {video_path.name}", video=video_path.name,
                                      has_truth=truth is not None, base_dir=out)
        written["report"] = write_text_atomic(out / plan["report"], text)
    # Earlier outputs stay listed while they exist; claims of a failed run that never wrote them lapse.
    files = {f for f in earlier if (out / f).exists()} | {plan[k] for k in written}
    written["manifest"] = _write_manifest(out, video_path, files, timings, complete=True)
    return written


def _write_manifest(out: Path, video_path: Path, files: set[str], timings: Mapping[str, float],
                    complete: bool) -> Path:
    manifest = {"format": MANIFEST_FORMAT, "video": str(video_path), "files": sorted(files | {MANIFEST_NAME}),
                "timings": dict(timings), "complete": complete}
    return write_text_atomic(out / MANIFEST_NAME, json.dumps(manifest, indent=1, sort_keys=True))
