"""CLI commands of the scene area: ``shots`` (cut detection) and ``two-view`` (relative pose of two images)."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Optional

import typer

from multithumbs.errors import InputError


def _parse_intrinsics(text: str) -> tuple[float, float, float, float]:
    parts = text.split(",")
    try:
        values = tuple(float(p) for p in parts)
    except ValueError:
        values = ()
    if len(values) != 4 or not all(math.isfinite(v) for v in values) or values[0] <= 0 or values[1] <= 0:
        raise InputError(f"--intrinsics: expected fx,fy,cx,cy with positive focal lengths, got {text!r}")
    return values  # type: ignore[return-value]


def _read_image(path: Path):
    import cv2

    if not path.is_file():
        raise InputError(f"{path}: no such image file")
    bgr = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if bgr is None:
        raise InputError(f"{path}: not an image OpenCV can read")
    return cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)


FAILED_EXIT_CODE = 2
"""Exit code of ``two-view`` when no geometry could be estimated (the same code as an input error: the
images do not allow what was asked)."""


def two_view_status(path: str, num_matches: int, num_inliers: int, min_inliers: int) -> tuple[str, bool]:
    """What a ``two-view`` result means, in one line: ``(status, estimated)``.

    Parameters
    ----------
    path : str
        The path that ran (``SharedSpace.fallback``, ``"two_view"`` when none did).
    num_matches, num_inliers : int
        Feature matches between the images and inliers of the relative pose.
    min_inliers : int
        The fewest inliers the estimator trusts (``TwoViewConfig.min_inliers``).

    Returns
    -------
    status : str
        ``"ok"`` for a relative pose with scene points; ``"partial: ..."`` for a rotation without
        translation; ``"failed: <why>"`` when nothing was estimated (the identity pose in the output is
        then a placeholder, not a measurement).
    estimated : bool
        False exactly when the status is ``"failed: ..."``.
    """
    if path == "rotation_only":
        return ("partial: rotation only (too little parallax for a translation; no scene points triangulated)",
                True)
    if path == "human_only" or num_inliers == 0:
        if num_matches < min_inliers:
            why = f"only {num_matches} feature matches between the images (need at least {min_inliers})"
        else:
            why = (f"{num_matches} feature matches but fewer than {min_inliers} agree on one relative pose "
                   "(unrelated images, or a degenerate view pair)")
        return f"failed: {why}; the reported pose is a placeholder (identity)", False
    return "ok", True


def register(app: typer.Typer) -> None:
    """Add ``shots`` and ``two-view`` to the app."""

    @app.command("shots")
    def shots_cmd(
        video: Path = typer.Argument(..., help="Video file."),
        detector: str = typer.Option("adaptive", "--detector", help="adaptive, content or histogram."),
        threshold: Optional[float] = typer.Option(None, "--threshold", help="The detector's threshold "
                                                  "(adaptive ratio, content score or histogram drop)."),
        min_shot_length: int = typer.Option(8, "--min-shot-length", help="Fewest frames of a shot."),
        as_json: bool = typer.Option(False, "--json", help="Print cut frames and per-frame scores as JSON."),
    ) -> None:
        """Detect the cuts of a video with PySceneDetect."""
        from rich.console import Console

        from multithumbs.extras import require

        require("scenedetect", "multithumbs shots")
        from multithumbs.scene.shots import ShotConfig, detect_shots

        key = {"adaptive": "adaptive_threshold", "content": "content_threshold",
               "histogram": "histogram_threshold"}.get(detector)
        if key is None:
            raise InputError(f"--detector {detector!r}: choose adaptive, content or histogram")
        options = {"detector": detector, "min_shot_length": min_shot_length}
        if threshold is not None:
            options[key] = threshold
        shots = detect_shots(video, ShotConfig(**options))
        if as_json:
            print(json.dumps({"video": str(video), "detector": shots.source, "fps": shots.fps,
                              "num_frames": shots.num_frames, "cut_frames": shots.cut_frames.tolist(),
                              "outlier_frames": shots.outlier_frames.tolist(),
                              "scores": [round(float(s), 4) for s in shots.scores]}))
            return
        Console().print(f"{video}: {shots.num_frames} frames at {shots.fps:g} fps, {shots.num_shots} shots, "
                        f"cuts at {shots.cut_frames.tolist()} ({shots.source})")

    @app.command("two-view")
    def two_view_cmd(
        image_a: Path = typer.Argument(..., help="First image (the frame before the cut)."),
        image_b: Path = typer.Argument(..., help="Second image (the frame after the cut)."),
        intrinsics: Optional[str] = typer.Option(None, "--intrinsics", help="fx,fy,cx,cy in pixels (default: "
                                                 "a 60-degree horizontal field of view, centred)."),
        mask_a: Optional[Path] = typer.Option(None, "--mask-a", help="People mask of IMAGE_A (an image; "
                                              "non-zero pixels are people, left out of the pose)."),
        mask_b: Optional[Path] = typer.Option(None, "--mask-b", help="People mask of IMAGE_B."),
        as_json: bool = typer.Option(False, "--json", help="Print the result as JSON."),
    ) -> None:
        """Relative pose and triangulated points of two images (the shared space at a cut, pycolmap)."""
        import numpy as np
        from rich.console import Console

        from multithumbs.geometry import intrinsics as make_intrinsics
        from multithumbs.scene.two_view import default_intrinsics, estimate_two_view
        from multithumbs.scene.two_view_pose import TwoViewConfig

        a, b = _read_image(image_a), _read_image(image_b)
        if a.shape != b.shape:
            raise InputError(f"{image_b}: size {b.shape[1]}x{b.shape[0]} differs from {image_a}'s "
                             f"{a.shape[1]}x{a.shape[0]}")
        K = make_intrinsics(*_parse_intrinsics(intrinsics)) if intrinsics else default_intrinsics(a.shape[1], a.shape[0])
        masks = []
        for path in (mask_a, mask_b):
            mask = None if path is None else _read_image(path).any(axis=2)
            if mask is not None and mask.shape != a.shape[:2]:
                raise InputError(f"{path}: mask size {mask.shape[1]}x{mask.shape[0]} differs from the images'")
            masks.append(mask)
        config = TwoViewConfig()
        result = estimate_two_view(a, b, K, masks[0], masks[1], config=config)
        space = result.space
        R = space.R[1] @ space.R[0].T
        t = space.t[1] - R @ space.t[0]
        norm = float(np.linalg.norm(t))
        direction = (t / norm).tolist() if norm > 0 else [0.0, 0.0, 0.0]
        angle = float(np.degrees(np.arccos(np.clip((np.trace(R) - 1) / 2, -1, 1))))
        route = space.fallback or "two_view"
        status, estimated = two_view_status(route, result.num_matches, result.num_inliers, config.min_inliers)
        out = {"status": status, "rotation": R.tolist(), "rotation_angle_deg": angle,
               "translation_direction": direction, "num_matches": result.num_matches,
               "num_inliers": result.num_inliers, "num_triangulated": result.num_triangulated, "path": route,
               "intrinsics": K.tolist()}
        if status != "ok":
            # stderr, in both modes: the JSON on stdout stays parseable and a script's user still sees it.
            Console(stderr=True).print(f"warning: {image_a.name} / {image_b.name}: {status}", style="yellow",
                                       markup=False, highlight=False)
        if as_json:
            print(json.dumps(out))
        elif not estimated:
            Console().print(f"path {route}: no relative pose estimated ({result.num_inliers} inliers of "
                            f"{result.num_matches} matches)", markup=False)
        else:
            Console().print(f"path {route}: rotation {angle:.2f} deg, translation direction "
                            f"{np.round(direction, 3).tolist()}, {result.num_inliers} inliers of "
                            f"{result.num_matches} matches, {result.num_triangulated} triangulated points",
                            markup=False)
        if not estimated:
            raise SystemExit(FAILED_EXIT_CODE)
