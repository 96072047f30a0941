import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
from typer.testing import CliRunner

from multithumbs.cli import app
from tests.viz.test_plots import bench_summary

runner = CliRunner()


def test_export_command(small_scene, tmp_path):
    points = tmp_path / "points.npz"
    np.savez(points, cut_0=np.random.default_rng(0).uniform(-1, 1, (10, 3)))
    out = tmp_path / "out"
    result = runner.invoke(app, ["export", str(small_scene.truth_path), "--video", str(small_scene.video_path),
                                 "--out", str(out), "--truth", str(small_scene.truth_path), "--scene-points",
                                 str(points), "--skip", "overlay,rrd", "--glb-stride", "2", "--json"])
    assert result.exit_code == 0, result.output
    written = json.loads(result.stdout)
    assert "overlay" not in written and "rrd" not in written and Path(written["glb"]).is_file()
    report = (out / "report.md").read_text()
    assert "| w_mpjpe | " in report  # metrics computed against the truth
    # A second run may replace its own files.
    again = runner.invoke(app, ["export", str(small_scene.truth_path), "--video", str(small_scene.video_path),
                                "--out", str(out), "--skip", "overlay,rrd,glb,bvh,colmap"])
    assert again.exit_code == 0, again.output


def run_cli(*args):
    exe = Path(sys.executable).parent / "multithumbs"
    return subprocess.run([str(exe), *args], capture_output=True, text=True, env=os.environ.copy(), timeout=300)


def test_export_errors_are_one_line(small_scene, tmp_path):
    done = run_cli("export", str(small_scene.truth_path), "--video", str(tmp_path / "none.mp4"), "--out",
                   str(tmp_path / "o"), "--skip", "overlay")
    assert done.returncode == 2 and done.stderr.strip().startswith("error:") and len(done.stderr.strip().splitlines()) == 1
    assert "none.mp4: no such video file" in done.stderr
    bad = runner.invoke(app, ["export", str(small_scene.truth_path), "--video", str(small_scene.video_path),
                              "--out", str(tmp_path / "o"), "--skip", "pdf"])
    assert bad.exit_code != 0 and "unknown output 'pdf'" in str(bad.exception)
    points = tmp_path / "p.npz"
    np.savez(points, other=np.zeros((2, 3)))
    bad = runner.invoke(app, ["export", str(small_scene.truth_path), "--video", str(small_scene.video_path),
                              "--out", str(tmp_path / "o"), "--scene-points", str(points)])
    assert bad.exit_code != 0 and "missing array 'cut_0'" in str(bad.exception)


def test_bench_plot_command(tmp_path):
    summary = tmp_path / "bench.json"
    summary.write_text(json.dumps(bench_summary()))
    result = runner.invoke(app, ["bench-plot", str(summary), "--out", str(tmp_path / "plots"), "--metrics", "w_mpjpe"])
    assert result.exit_code == 0, result.output
    assert sorted(p.name for p in (tmp_path / "plots").iterdir()) == ["bench_w_mpjpe.png", "bench_w_mpjpe.svg"]
    refused = runner.invoke(app, ["bench-plot", str(summary), "--out", str(tmp_path / "plots"), "--metrics", "w_mpjpe"])
    assert refused.exit_code != 0 and "already exists" in str(refused.exception)
    unknown = runner.invoke(app, ["bench-plot", str(summary), "--out", str(tmp_path / "plots"), "--metrics", "x"])
    assert unknown.exit_code != 0 and "'x' is not in" in str(unknown.exception)
