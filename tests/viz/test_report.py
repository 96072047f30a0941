import math

import numpy as np

from multithumbs.viz.report import flatten_metrics, render_report_markdown


def test_report_sections(small_scene, tmp_path):
    world = small_scene.world
    files = {"trajectory_png": tmp_path / "trajectory.png", "overlay": tmp_path / "overlay.mp4",
             "glb": tmp_path / "scene.glb"}
    text = render_report_markdown(
        world, files, {"w_mpjpe": 123.456, "ids": 2, "pck": {"005": 0.9}, "ate": None, "curve": [1, 2]},
        {"backends": {"shots": "scenedetect:adaptive", "cameras": "pycolmap"},
         "fallbacks": {"shared_space": "no scene match at cut 60: identity placement"},
         "timings": {"shots": 1.5, "align": 10.25}, "variant": "full"},
        video="clip.mp4", has_truth=True, base_dir=tmp_path)
    assert text.startswith("# ")
    for heading in ("## Summary", "## Metrics", "## Pictures", "## Backends and fallbacks", "## Timings", "## Run",
                    "## Files"):
        assert heading in text
    # Evaluation numbers carry their unit; how each sequence's ATE was aligned is shown as text.
    assert "| w_mpjpe | 123.5 | mm |" in text and "| pck.005 | 0.9 |  |" in text and "| ate | n/a | m |" in text
    assert "| ids | 2 | switches/sequence |" in text
    assert "curve" not in text
    aligned = render_report_markdown(world, files, {"ate": 0.1, "ate_alignment": ["sim3_camera_centres"]})
    assert "| ate_alignment | sim3_camera_centres |  |" in aligned
    assert "![Top-down trajectories](trajectory.png)" in text
    assert "left: result, right: ground truth" in text
    assert "| shots | scenedetect:adaptive |" in text
    assert "- shared_space: no scene match at cut 60: identity placement" in text
    assert "| **total** | 11.75 |" in text
    assert "| variant | full |" in text
    assert f"| cuts (first frame of the new shot) | {int(world.cut_frames[0])} |" in text
    assert "[scene.glb](scene.glb)" in text


def test_report_without_anything(small_scene):
    text = render_report_markdown(small_scene.world)
    assert "No metrics (no ground truth given)." in text
    assert "Backends not recorded." in text and "No fallback ran." in text
    assert "## Pictures" not in text


def test_flatten_metrics():
    flat = flatten_metrics({"a": 1, "b": {"c": 2.5, "d": {"e": np.float32(3)}}, "f": None, "g": np.arange(3),
                            "h": "note"})
    assert flat["a"] == 1 and flat["b.c"] == 2.5 and flat["b.d.e"] == 3 and math.isnan(flat["f"])
    assert "g" not in flat and flat["h"] == "note"


def test_report_says_where_a_cuts_cameras_came_from(small_scene):
    import dataclasses

    world = small_scene.world
    assert "Boundary cameras not from the scene" not in render_report_markdown(world)
    cuts = len(world.cut_frames)
    for code, phrase in ((1, "from the people seen on both sides"), (2, "the cameras across it are unknown")):
        diagnostics = {**world.diagnostics, **{f"cameras_from_cut{c}": np.int64(code) for c in range(cuts)}}
        text = render_report_markdown(dataclasses.replace(world, diagnostics=diagnostics))
        assert "Boundary cameras not from the scene:" in text and "- cut 0: " in text and phrase in text
