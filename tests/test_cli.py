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


# --- output at 80 columns -------------------------------------------------------------------------------

def invoke_at_80(monkeypatch, *args):
    """The command in-process through typer's CliRunner with an 80-column terminal."""
    from typer.testing import CliRunner

    from multithumbs.cli import app

    monkeypatch.setenv("COLUMNS", "80")
    result = CliRunner().invoke(app, [str(a) for a in args], env={"COLUMNS": "80"}, catch_exceptions=False)
    assert result.exit_code == 0, result.output
    return result.output


def assert_fits_80(text):
    too_wide = [line for line in text.splitlines() if len(line) > 80]
    assert not too_wide, "\n".join(too_wide)


def test_suite_table_fits_80_columns_with_every_scene_name_whole(monkeypatch):
    from multithumbs.synth.suite import suite

    text = invoke_at_80(monkeypatch, "suite")
    assert_fits_80(text)
    for config in suite("standard"):  # the names --scene takes, each whole on one line
        assert any(config.name in line for line in text.splitlines()), config.name
    assert "walking abreast" in text and "moving cameras" in text


@pytest.mark.parametrize("command", ["run", "demo", "synth", "eval", "bench", "suite"])
def test_help_fits_80_columns_and_flags_show_no_type(monkeypatch, command):
    text = invoke_at_80(monkeypatch, command, "--help")
    assert_fits_80(text)
    assert "<bool>" not in text
    if command in ("run", "demo", "synth", "eval"):
        assert "--smpl-model" in text


def test_bench_table_fits_80_columns_with_units(monkeypatch):
    import multithumbs.bench as bench
    from multithumbs.metrics.evaluate import METRIC_UNITS
    from multithumbs.pipeline import VARIANTS

    monkeypatch.setattr(bench, "run_suite", lambda configs, names, workers, progress, perception="direct", inputs="simulated",
                        pixel_stages=None, input_cache=None: [])
    monkeypatch.setattr(bench, "summarize", lambda results, names: {
        v: {k: {"mean": 1234.5678 if k == "w_mpjpe" else 0.5} for k in bench.METRIC_KEYS} for v in names})
    text = invoke_at_80(monkeypatch, "bench")
    assert_fits_80(text)
    lines = text.splitlines()
    for variant in VARIANTS:  # every variant's name whole, in each of the tables
        assert any(line.lstrip().startswith(variant + " ") for line in lines), variant
    for key in bench.METRIC_KEYS:
        assert any(key in line.split() for line in lines), key
    assert "switches/sequence" in text and METRIC_UNITS["accel"] in text
    assert "backends:" in text


def _keep_env(monkeypatch, name: str) -> None:
    """Restore ``name`` after the test, absent if it was absent (an empty value is not absent)."""
    if name in os.environ:
        monkeypatch.setenv(name, os.environ[name])
    else:  # setenv records "absent" for the undo, delenv makes it absent now
        monkeypatch.setenv(name, "")
        monkeypatch.delenv(name)


def _no_prefect_api(monkeypatch) -> None:
    """The flow is faked in these layout tests: no Prefect API to start or wait for."""
    import multithumbs.cli as cli

    monkeypatch.setattr(cli, "start_flow_api", lambda: None)
    monkeypatch.setattr(cli, "flow_logging", lambda: None)


def test_demo_title_is_one_line_and_fits_80_columns(monkeypatch, tmp_path):
    import flows.reconstruct
    from multithumbs.bench import METRIC_KEYS

    for name in ("PREFECT_HOME", "PREFECT_SERVER_ANALYTICS_ENABLED", "PREFECT_LOGGING_LEVEL",
                 "PREFECT_SERVER_EPHEMERAL_STARTUP_TIMEOUT_SECONDS"):
        _keep_env(monkeypatch, name)  # restored afterwards: the demo sets them
    _no_prefect_api(monkeypatch)
    monkeypatch.setattr(flows.reconstruct, "reconstruct_synthetic",
                        lambda *a, **k: {key: 12.345 for key in METRIC_KEYS})
    text = invoke_at_80(monkeypatch, "demo", "--out", tmp_path / "demo")
    assert_fits_80(text)
    lines = [line for line in text.splitlines() if line.strip()]
    assert lines[0].strip() == "s09_crossing_at_cut (full)"
    assert any("SIMULATED" in line and "camera tracking" in line for line in lines)
    assert any(line.split()[1:3] == ["mm/frame"] or "mm/frame" in line for line in lines)


def test_run_lists_outputs_with_their_subfolders(monkeypatch, tmp_path, tiny_video):
    import flows.video

    out = tmp_path / "out"
    files = {"result": out / "result.npz", "smpl_0": out / "smpl" / "person_0.npz",
             "bvh_0": out / "bvh" / "person_0.bvh", "colmap": out / "colmap" / "images.txt"}
    for name in ("PREFECT_HOME", "PREFECT_SERVER_ANALYTICS_ENABLED", "PREFECT_LOGGING_LEVEL",
                 "PREFECT_SERVER_EPHEMERAL_STARTUP_TIMEOUT_SECONDS"):
        _keep_env(monkeypatch, name)
    _no_prefect_api(monkeypatch)
    seen = {}

    def fake_flow(*args, **kwargs):
        seen.update(kwargs)
        return {"num_shots": 2, "files": {k: str(v) for k, v in files.items()},
                "backends": {"shots": "scenedetect:adaptive", "perception": "phalp",
                             "camera tracking": "pycolmap", "shared space": "pycolmap two-view"},
                "timings": {"shot detection": 1.0, "perception": 0.5}, "metrics": {"w_mpjpe": 123.4, "ids": 0}}

    monkeypatch.setattr(flows.video, "reconstruct_video", fake_flow)
    smpl = tmp_path / "my_smpl.npz"
    smpl.write_bytes(b"not read: the flow is replaced")
    text = invoke_at_80(monkeypatch, "run", tiny_video / "video.mp4", "--out", out, "--perception",
                        f"phalp:{tiny_video / 'perception.pkl'}", "--trust-pickle", "--smpl-model", smpl)
    assert_fits_80(text)
    for rel in ("result.npz", "smpl/person_0.npz", "bvh/person_0.bvh", "colmap/images.txt"):
        assert rel in text, rel
    assert "mm" in text and seen["smpl_model"] == str(smpl.resolve())


def test_flow_environment_turns_prefect_telemetry_off_unless_the_user_chose(monkeypatch, tmp_path):
    from multithumbs.cli_runtime import flow_environment as _flow_environment

    env = {"MULTITHUMBS_CACHE": str(tmp_path), "DO_NOT_TRACK": "0"}
    monkeypatch.setattr(os, "environ", env)
    _flow_environment()
    assert env["PREFECT_SERVER_ANALYTICS_ENABLED"] == "false"
    assert env["DO_NOT_TRACK"] == "0"  # the user's own value wins
    assert env["PREFECT_HOME"] == str(tmp_path / "prefect")
    env.clear()
    env["MULTITHUMBS_CACHE"] = str(tmp_path)
    _flow_environment()
    assert env["DO_NOT_TRACK"] == "1"
