"""The outputs task: a video's result, pictures, exports and report written to its output folder."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
from prefect import task
from prefect.cache_policies import NO_CACHE

from storage.store import ArtifactRef
from tasks.artifacts import load

STAMP_NAME = ".multithumbs-outputs.json"
"""Which result the folder's outputs show (so a re-run of the same result writes nothing)."""

MAX_SCENE_POINTS = 20000
"""Scene points per cut kept for the exports (a random subset, fixed seed, when there are more)."""


def world_scene_points(spaces: list[ArtifactRef], method_refs: dict[str, ArtifactRef]) -> list[np.ndarray]:
    """Every cut's scene points in the world frame: the space scaled by its alignment, then placed."""
    if "placement" not in method_refs:
        return []
    placement = load(method_refs["placement"])
    points = []
    for c, space_ref in enumerate(spaces):
        if f"aligned_{c}" not in method_refs or c >= len(placement.space_to_world):
            continue
        scale = float(load(method_refs[f"aligned_{c}"]).scale)
        xyz = load(space_ref).points * (scale if np.isfinite(scale) else 1.0)
        if len(xyz) > MAX_SCENE_POINTS:
            xyz = xyz[np.random.default_rng(0).choice(len(xyz), MAX_SCENE_POINTS, replace=False)]
        m = placement.space_to_world[c]
        points.append(xyz @ m[:3, :3].T + m[:3, 3])
    return points


@task(name="outputs", cache_policy=NO_CACHE, retries=1)
def write_outputs(out_dir: str, name: str, variant: str, video_path: str, method_refs: dict[str, ArtifactRef],
                  spaces: list[ArtifactRef], truth: ArtifactRef | None, metrics: dict[str, Any] | None,
                  run_info: dict[str, Any], smpl_model: str | None = None) -> dict[str, str]:
    """Write ``result.npz``, ``metrics.json`` (with ground truth), the overlay video, plots, exports and
    ``report.md`` into ``out_dir``, meshes posed with ``smpl_model`` (None: the procedural body); returns
    output name -> path."""
    out = Path(out_dir)
    stamp_path = out / STAMP_NAME
    stamp = {"result": method_refs["result"].key, "metrics": metrics, "video": str(video_path),
             "body": smpl_model}
    if stamp_path.exists():  # the same result's outputs are already there: a re-run writes nothing
        try:
            previous = json.loads(stamp_path.read_text())
            # Compared as JSON text: metrics may hold NaN (e.g. an undefined ATE), and NaN != NaN.
            same = json.dumps(previous.get("stamp"), sort_keys=True) == json.dumps(stamp, sort_keys=True)
            if same and all(Path(f).exists() for f in previous["files"].values()):
                return previous["files"]
        except (ValueError, KeyError, TypeError):
            pass
    # Imported only when something is written: a re-run whose stamp matches imports neither torch nor
    # the pictures' libraries.
    from multithumbs.body.model import load_body_model
    from multithumbs.io import save_result
    from multithumbs.viz.outputs import write_video_outputs

    result = load(method_refs["result"])
    files = {"result": str(save_result(out / "result.npz", result, metadata={
        "variant": variant, "name": name, "artifact": method_refs["result"].key, "backends": run_info["backends"]}))}
    if metrics is not None:
        # Which backend produced each stage travels with the figures it produced.
        (out / "metrics.json").write_text(json.dumps({**metrics, "backends": run_info["backends"]}, indent=2,
                                                     sort_keys=True))
        files["metrics"] = str(out / "metrics.json")
    written = write_video_outputs(out, result, video_path, truth=None if truth is None else load(truth),
                                  metrics=metrics, run_info=run_info,
                                  scene_points=world_scene_points(spaces, method_refs) or None,
                                  body=load_body_model(smpl_model), title=f"{name} ({variant})")
    files.update({k: str(v) for k, v in written.items()})
    stamp_path.write_text(json.dumps({"stamp": stamp, "files": files}, indent=1, sort_keys=True))
    return files
