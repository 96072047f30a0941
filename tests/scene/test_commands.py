import json
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest
from typer.testing import CliRunner

from multithumbs.cli import app
from multithumbs.errors import InputError
from multithumbs.scene.commands import two_view_status
from multithumbs.synth.files import write_video
from tests.scene.conftest import rotation_error_deg

EXE = str(Path(sys.executable).with_name("multithumbs"))


def test_shots_json(static_clip, tmp_path):
    path = write_video(tmp_path / "clip.mp4", static_clip.video.frames, 30.0)
    result = CliRunner().invoke(app, ["shots", str(path), "--json"])
    assert result.exit_code == 0, result.output
    out = json.loads(result.stdout)
    assert out["cut_frames"] == static_clip.world.cut_frames.tolist()
    assert len(out["scores"]) == out["num_frames"] == len(static_clip.video.frames)
    content = CliRunner().invoke(app, ["shots", str(path), "--json", "--detector", "content", "--threshold", "250"])
    assert json.loads(content.stdout)["cut_frames"] == []


def test_two_view_json(static_clip, tmp_path):
    cut = int(static_clip.world.cut_frames[0])
    w = static_clip.world
    for name, f in (("a", cut - 1), ("b", cut)):
        cv2.imwrite(str(tmp_path / f"{name}.png"), cv2.cvtColor(static_clip.video.frames[f], cv2.COLOR_RGB2BGR))
        cv2.imwrite(str(tmp_path / f"{name}_mask.png"), (static_clip.video.instance[f] >= 0).astype(np.uint8) * 255)
    K = w.K[cut]
    intr = f"{K[0, 0]},{K[1, 1]},{K[0, 2]},{K[1, 2]}"
    result = CliRunner().invoke(app, ["two-view", str(tmp_path / "a.png"), str(tmp_path / "b.png"),
                                      "--intrinsics", intr, "--mask-a", str(tmp_path / "a_mask.png"),
                                      "--mask-b", str(tmp_path / "b_mask.png"), "--json"])
    assert result.exit_code == 0, result.output
    out = json.loads(result.stdout)
    R_true = w.R[cut] @ w.R[cut - 1].T
    assert rotation_error_deg(np.array(out["rotation"]), R_true) < 1.0
    assert out["status"] == "ok" and out["path"] in ("two_view", "with_people") and out["num_inliers"] >= 30
    assert out["num_triangulated"] > 0 and abs(np.linalg.norm(out["translation_direction"]) - 1) < 1e-9


def test_errors_are_one_line(tmp_path):
    (tmp_path / "a.png").write_bytes(b"junk")
    cv2.imwrite(str(tmp_path / "b.png"), np.zeros((20, 20, 3), np.uint8))
    for args, words in ((["two-view", str(tmp_path / "a.png"), str(tmp_path / "a.png")], "not an image"),
                        (["two-view", str(tmp_path / "none.png"), str(tmp_path / "none.png")], "no such image"),
                        (["two-view", str(tmp_path / "b.png"), str(tmp_path / "b.png"), "--intrinsics", "1,2"],
                         "--intrinsics"),
                        (["shots", str(tmp_path / "none.mp4")], "no such video")):
        result = CliRunner().invoke(app, args)
        assert isinstance(result.exception, InputError) and words in str(result.exception), args


@pytest.mark.slow
def test_entry_point_error_is_one_line(tmp_path):
    """Through the installed entry point: one line on stderr, exit code 2 (slow: a fresh interpreter)."""
    proc = subprocess.run([EXE, "shots", str(tmp_path / "none.mp4")], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2 and proc.stderr.startswith("error: ") and proc.stderr.count("\n") == 1, proc.stderr


def test_two_view_without_geometry_says_so(tmp_path):
    """Blank and unrelated images: a "failed" status in the JSON, a warning, exit code 2 (was: exit 0, silent)."""
    rng = np.random.default_rng(0)
    cv2.imwrite(str(tmp_path / "blank.png"), np.full((120, 160, 3), 128, np.uint8))
    cv2.imwrite(str(tmp_path / "noise_a.png"), rng.integers(0, 256, (120, 160, 3), dtype=np.uint8))
    cv2.imwrite(str(tmp_path / "noise_b.png"), rng.integers(0, 256, (120, 160, 3), dtype=np.uint8))
    for a, b in (("blank", "blank"), ("noise_a", "noise_b")):
        args = ["two-view", str(tmp_path / f"{a}.png"), str(tmp_path / f"{b}.png"), "--intrinsics", "150,150,80,60"]
        result = CliRunner().invoke(app, [*args, "--json"])
        assert result.exit_code == 2, (a, b, result.output)
        out = json.loads(result.stdout)
        assert out["status"].startswith("failed: ") and out["num_inliers"] == 0, out
        assert "warning:" in result.stderr and "failed" in result.stderr
        human = CliRunner().invoke(app, args)
        assert human.exit_code == 2 and "warning:" in human.stderr and "no relative pose" in human.stdout


def test_two_view_status():
    assert two_view_status("two_view", 200, 150, 30) == ("ok", True)
    assert two_view_status("with_people", 200, 150, 30) == ("ok", True)
    status, estimated = two_view_status("rotation_only", 200, 0, 30)
    assert estimated and status.startswith("partial: ")
    status, estimated = two_view_status("human_only", 3, 0, 30)
    assert not estimated and status.startswith("failed: ") and "3 feature matches" in status
    status, estimated = two_view_status("human_only", 300, 0, 30)
    assert not estimated and "fewer than 30 agree" in status
