import json
import os
import subprocess
import sys

import pytest


def run_cli(*args, env_extra=None):
    env = dict(os.environ, **(env_extra or {}))
    return subprocess.run([sys.executable, "-m", "multithumbs.cli", *map(str, args)], capture_output=True,
                          text=True, env=env, timeout=600)


@pytest.mark.parametrize("args,needle", [
    (["--people", "0"], "people"),
    (["--shots", "5", "--frames", "4"], "frames"),
    (["--cut-angle", "400"], "cut-angle"),
])
def test_synth_rejects_impossible_parameters(tmp_path, args, needle):
    out = run_cli("synth", "--out", tmp_path / "o", *args)
    assert out.returncode == 2
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0] and "Traceback" not in out.stderr
    assert not (tmp_path / "o" / "video.mp4").exists()


def test_synth_rejects_an_unwritable_output(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    out = run_cli("synth", "--out", blocker / "sub", "--frames", "4")
    assert out.returncode == 2 and len(out.stderr.strip().splitlines()) == 1
    assert blocker.read_text() == "not a folder"


def test_synth_then_eval_ground_truth_against_itself(tmp_path):
    out_dir = tmp_path / "scene"
    out = run_cli("synth", "--out", out_dir, "--people", "2", "--shots", "2", "--frames", "8",
                  "--width", "320", "--height", "180", "--seed", "3")
    assert out.returncode == 0, out.stderr
    for name in ("video.mp4", "ground_truth.npz", "contact_sheet.png"):
        assert (out_dir / name).stat().st_size > 0
    # Existing outputs are never overwritten silently.
    again = run_cli("synth", "--out", out_dir, "--frames", "8")
    assert again.returncode == 2 and "already exists" in again.stderr
    gt = out_dir / "ground_truth.npz"
    scores = run_cli("eval", gt, gt, "--json")
    assert scores.returncode == 0, scores.stderr
    metrics = json.loads(scores.stdout)
    for key in ("w_mpjpe", "wa_mpjpe", "mpjpe", "pa_mpjpe", "mpvpe", "accel", "ate", "ids"):
        assert metrics[key] == pytest.approx(0.0, abs=1e-6), key
    assert metrics["ids"] == 0


def test_eval_names_a_missing_file(tmp_path):
    out = run_cli("eval", tmp_path / "nope.npz", tmp_path / "gt.npz")
    assert out.returncode == 2 and "nope.npz" in out.stderr and len(out.stderr.strip().splitlines()) == 1


@pytest.mark.parametrize("args,needle", [
    (["nosuchcmd"], "No such command"),
    (["synth", "--people", "x", "--out", "o"], "--people"),
    (["synth"], "--out"),
    (["bench", "--variants", "bogus"], "bogus"),
])
def test_usage_errors_are_one_line_with_exit_code_2(args, needle):
    out = run_cli(*args)
    assert out.returncode == 2 and "Traceback" not in out.stderr
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0]


@pytest.fixture(scope="module")
def tiny_video(tmp_path_factory):
    """A two-shot synthetic video with its SIMULATED perception file (as `multithumbs synth` writes them)."""
    out_dir = tmp_path_factory.mktemp("run") / "scene"
    out = run_cli("synth", "--out", out_dir, "--people", "2", "--shots", "2", "--frames", "8",
                  "--width", "320", "--height", "180", "--seed", "5")
    assert out.returncode == 0, out.stderr
    assert (out_dir / "perception.pkl").stat().st_size > 0
    return out_dir


def test_run_rejects_bad_input_before_starting(tmp_path, tiny_video):
    """Each case: one line naming the input, exit code 2, nothing written."""
    video, pkl = tiny_video / "video.mp4", f"phalp:{tiny_video / 'perception.pkl'}"
    empty = tmp_path / "empty.mp4"
    empty.write_bytes(b"")
    blocker = tmp_path / "file"
    blocker.write_text("x")
    cases = [
        (["run", tmp_path / "missing.mp4", "--out", tmp_path / "o", "--perception", pkl], "missing.mp4"),
        (["run", empty, "--out", tmp_path / "o", "--perception", pkl], "empty.mp4"),
        (["run", video, "--out", tmp_path / "o", "--perception", "openpose:x"], "openpose"),
        (["run", video, "--out", tmp_path / "o", "--perception", pkl], "--trust-pickle"),
        (["run", video, "--out", blocker / "sub", "--perception", pkl, "--trust-pickle"], "file"),
        (["run", video, "--out", tmp_path / "o", "--perception", pkl, "--trust-pickle", "--set", "reid.nope=1"],
         "reid.nope"),
        (["run", video, "--out", tmp_path / "o", "--perception", pkl, "--trust-pickle", "--intrinsics", "1,2"],
         "intrinsics"),
    ]
    for args, needle in cases:
        out = run_cli(*args)
        lines = out.stderr.strip().splitlines()
        assert out.returncode == 2 and len(lines) == 1 and needle in lines[0], (args, out.stderr)
    assert not (tmp_path / "o").exists()
