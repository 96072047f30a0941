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
    assert out["path"] in ("two_view", "with_people") and out["num_inliers"] >= 30
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
