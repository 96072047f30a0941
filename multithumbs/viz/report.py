"""The per-video report as markdown: summary, people and their shots, metrics, pictures, files, backends and
fallbacks, timings.

``run_info`` (all keys optional; what the flow or the CLI knows about the run):

- ``"backends"``: ``{stage: backend label}``, e.g. ``{"shots": "scenedetect:adaptive", "cameras": "pycolmap"}``.
- ``"fallbacks"``: ``{stage: what ran instead}`` or a list of strings; empty when none ran.
- ``"timings"``: ``{stage: seconds}`` of the reconstruction stages.
- ``"export_timings"``: ``{output: seconds}`` (filled by :func:`multithumbs.viz.outputs.write_video_outputs`).
- any other key with a scalar value: listed under "Run".
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from multithumbs.metric_names import report_rows

from multithumbs.types import WorldResult

_PICTURES = (("trajectory_png", "Top-down trajectories"),)


def _fmt(value: Any) -> str:
    if isinstance(value, (bool, np.bool_)):
        return "yes" if value else "no"
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if isinstance(value, (float, np.floating)):
        v = float(value)
        if not math.isfinite(v):
            return "n/a"
        return f"{v:.4g}" if abs(v) < 1e4 else f"{v:.0f}"
    return str(value).replace("|", "\\|").replace("\n", " ")


def flatten_metrics(metrics: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    """Scalar entries of a (nested) metrics dict, nested keys joined with ``.``; arrays and lists are skipped."""
    out: dict[str, Any] = {}
    for key, value in metrics.items():
        name = f"{prefix}{key}"
        if isinstance(value, Mapping):
            out.update(flatten_metrics(value, name + "."))
        elif value is None:
            out[name] = math.nan
        elif isinstance(value, (int, float, bool, np.integer, np.floating, np.bool_)):
            out[name] = value
        elif isinstance(value, str):
            out[name] = value
    return out


def _table(header: tuple[str, ...], rows: list[tuple[str, ...]]) -> list[str]:
    """A markdown table, the first column left-aligned and the others right-aligned."""
    return ["| " + " | ".join(header) + " |", "| --- |" + " ---: |" * (len(header) - 1),
            *("| " + " | ".join(row) + " |" for row in rows)]


def _cut_cameras(result: WorldResult) -> list[str]:
    """One line per cut whose boundary cameras came from the people, or from nothing (diagnostics
    ``cameras_from_cut{c}``: 0 scene, 1 people, 2 none)."""
    rows = []
    for c in range(len(result.cut_frames)):
        code = result.diagnostics.get(f"cameras_from_cut{c}")
        if code is None or int(code) == 0:
            continue
        rows.append(f"- cut {c}: from the people seen on both sides of it" if int(code) == 1 else
                    f"- cut {c}: the scene gave no cameras and nobody was seen on both sides with enough body "
                    f"keypoints, so the cameras across it are unknown: identities there rest on appearance and "
                    f"pose, and the shots' relative placement is a guess")
    return rows


def people_by_shot(result: WorldResult) -> list[dict[str, Any]]:
    """Each person of ``result`` with the shots (numbered from 0) and frames they are seen in, by id."""
    starts = np.concatenate([[0], np.asarray(result.cut_frames, int)])
    out = []
    for index in np.argsort(result.person_ids, kind="stable"):
        frames = np.flatnonzero(result.valid[index])
        if frames.size == 0:
            continue
        shots = sorted({int(s) for s in np.searchsorted(starts, frames, side="right") - 1})
        out.append({"id": int(result.person_ids[index]), "shots": shots, "frames": int(frames.size),
                    "first": int(frames[0]), "last": int(frames[-1])})
    return out


def render_report_markdown(result: WorldResult, files: Mapping[str, str | Path] | None = None,
                           metrics: Mapping[str, Any] | None = None, run_info: Mapping[str, Any] | None = None,
                           title: str = "Multi-THuMBS reconstruction", video: str | None = None,
                           has_truth: bool = False, base_dir: str | Path | None = None) -> str:
    """The report (module docstring) as a markdown string.

    Args:
        result: the reconstruction.
        files: output kind -> path of what was written (pictures are embedded, the rest listed).
        metrics: metric name -> value (nested dicts are flattened); None when there is no ground truth.
        run_info: backends, fallbacks, timings (module docstring).
        title: first heading.
        video: the input video's name, shown in the summary.
        has_truth: whether ground truth was given (the overlay then has a truth panel).
        base_dir: paths in ``files`` are written relative to it (the report's folder), so links work.
    """
    info = dict(run_info or {})
    files = dict(files or {})

    def link(path: str | Path) -> str:
        p = Path(path)
        if base_dir is not None:
            try:
                p = p.resolve().relative_to(Path(base_dir).resolve())
            except ValueError:
                pass
        return p.as_posix()

    cuts = [int(c) for c in result.cut_frames]
    lines = [f"# {title}", ""]
    summary = [("video", video or "n/a"), ("frames", str(result.num_frames)), ("fps", _fmt(result.fps)),
               ("image size", f"{result.image_size[1]}x{result.image_size[0]}"),
               ("shots", str(len(cuts) + 1)), ("cuts (first frame of the new shot)", ", ".join(map(str, cuts)) or "none"),
               ("people (global ids)", ", ".join(str(int(i)) for i in result.person_ids) or "none"),
               ("valid person-frames", str(int(result.valid.sum()))), ("ground truth", "yes" if has_truth else "no")]
    lines += ["## Summary", "", *_table(("", ""), summary), ""]
    lines += ["## People", ""]
    people = people_by_shot(result)
    if people:
        lines += _table(("person (global id)", "shots", "frames", "first", "last"),
                        [(str(p["id"]), ", ".join(map(str, p["shots"])), str(p["frames"]), str(p["first"]),
                          str(p["last"])) for p in people])
    else:
        lines.append("Nobody was found in any shot: the result holds the cameras only.")
    lines.append("")

    lines += ["## Metrics", ""]
    flat = flatten_metrics(metrics) if metrics else {}
    if flat:
        # The evaluation's numbers with their units (headline first; docs/METRICS.md defines each), then
        # the rest (options, notes) as they come.
        rows = [r for r in report_rows(dict(metrics)) if not isinstance(r["value"], Mapping)]
        for r in rows:
            r["value"] = math.nan if r["value"] is None else r["value"]
        shown = {r["metric"] for r in rows}
        lines += ["| metric | value | unit |", "| --- | ---: | --- |",
                  *(f"| {r['metric']} | {_fmt(r['value'])} | {r['unit']} |" for r in rows)]
        lines += [f"| {k} | {_fmt(v)} |  |" for k, v in flat.items() if k not in shown]
    else:
        lines.append("No metrics (no ground truth given)." if not has_truth else "No metrics were computed.")
    lines.append("")

    pictures = [(files[k], caption) for k, caption in _PICTURES if k in files]
    if pictures or "overlay" in files:
        lines += ["## Pictures", ""]
        for path, caption in pictures:
            lines += [f"![{caption}]({link(path)})", ""]
        if "overlay" in files:
            side = " (left: result, right: ground truth)" if has_truth else ""
            lines += [f"Overlay video{side}: [{link(files['overlay'])}]({link(files['overlay'])})", ""]

    lines += ["## Backends and fallbacks", ""]
    backends = info.pop("backends", None) or {}
    fallbacks = info.pop("fallbacks", None) or {}
    if backends:
        lines += _table(("stage", "backend"), [(str(k), _fmt(v)) for k, v in backends.items()])
    else:
        lines.append("Backends not recorded.")
    lines.append("")
    if isinstance(fallbacks, Mapping):
        fallback_rows = [f"- {k}: {_fmt(v)}" for k, v in fallbacks.items() if v]
    else:
        fallback_rows = [f"- {_fmt(v)}" for v in fallbacks if v]
    lines += (["Fallbacks that ran:", "", *fallback_rows] if fallback_rows else ["No fallback ran."]) + [""]
    camera_rows = _cut_cameras(result)
    if camera_rows:
        lines += ["Boundary cameras not from the scene:", "", *camera_rows, ""]

    timings = info.pop("timings", None) or {}
    export_timings = info.pop("export_timings", None) or {}
    lines += ["## Timings", ""]
    if timings:
        total = sum(float(v) for v in timings.values())
        lines += _table(("stage", "seconds"), [(str(k), _fmt(float(v))) for k, v in timings.items()]
                        + [("**total**", _fmt(total))]) + [""]
    else:
        lines += ["Stage timings not recorded.", ""]
    if export_timings:
        lines += ["Outputs:", "", *_table(("output", "seconds"), [(str(k), _fmt(float(v)))
                                                                 for k, v in export_timings.items()]), ""]

    rest = [(str(k), _fmt(v)) for k, v in info.items() if isinstance(v, (str, int, float, bool, np.generic))]
    if rest:
        lines += ["## Run", "", *_table(("", ""), rest), ""]

    listed = [(k, p) for k, p in files.items() if k != "report"]
    if listed:
        lines += ["## Files", ""]
        lines += [f"- `{k}`: [{link(p)}]({link(p)})" for k, p in listed]
        lines.append("")
    return "\n".join(lines)
