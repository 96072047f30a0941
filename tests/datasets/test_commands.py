import json
import os
import subprocess
import sys

import torch
from typer.testing import CliRunner

from multithumbs.body.model import BodyModel
from multithumbs.body.procedural import build_procedural_smpl
from multithumbs.cli import app
from multithumbs.errors import InputError
from multithumbs.io import load_ground_truth
from tests.body.test_model import write_chumpy_pickle
from tests.datasets.fixtures import REC

runner = CliRunner()
SEQ = "01_tagging/001_tagging"


def run_cli(*args):
    return subprocess.run([sys.executable, "-m", "multithumbs.cli", *map(str, args)], capture_output=True, text=True,
                          env=dict(os.environ), timeout=600)


def test_list_describes_each_kind_of_root(egohumans, harmony4d, egobody, ava, sitcoms):
    out = runner.invoke(app, ["dataset", "list", str(egohumans[0]), "--json"])
    assert out.exit_code == 0, out.output
    info = json.loads(out.stdout)
    assert info["dataset"] == "egohumans"
    (seq,) = info["sequences"]
    assert seq["sequence"] == SEQ and seq["num_frames"] == 6 and seq["people"] == ["aria01", "aria02"]
    assert [c["name"] for c in seq["cameras"]] == ["cam01", "cam02"] and seq["cameras"][0]["model"] == "fisheye"
    expected = {harmony4d[0]: "harmony4d", egobody[0]: "egobody", ava[0]: "ava", sitcoms[0]: "sitcoms"}
    for root, kind in expected.items():
        out = runner.invoke(app, ["dataset", "list", str(root), "--json"])
        assert out.exit_code == 0, out.output
        assert json.loads(out.stdout)["dataset"] == kind
    eb = json.loads(runner.invoke(app, ["dataset", "list", str(egobody[0]), "--json"]).stdout)["sequences"][0]
    assert eb["sequence"] == REC and eb["frame_ids"] == [4, 7] and eb["split"] == "val"
    table = runner.invoke(app, ["dataset", "list", str(sitcoms[0])])
    assert table.exit_code == 0 and "TBBT" in table.stdout


def test_build_writes_clips_and_prints_them(egohumans, tmp_path):
    spec = tmp_path / "clip.toml"
    spec.write_text(f'name = "c"\ndataset = "egohumans"\nsequence = "{SEQ}"\ncameras = ["cam01", "cam02"]\n'
                    'cuts = [3]\nnum_frames = 6\n')
    out = runner.invoke(app, ["dataset", "build", str(spec), "--data-root", str(egohumans[0]), "--out",
                              str(tmp_path / "out"), "--json"])
    assert out.exit_code == 0, out.output
    assert json.loads(out.stdout) == {"c": str(tmp_path / "out" / "c")}
    gt, _ = load_ground_truth(tmp_path / "out" / "c" / "ground_truth.npz")
    assert gt.world.num_frames == 6


def invoke_error(*args):
    """The InputError a command raises (``multithumbs.cli.main`` prints it as one line, exit code 2)."""
    out = runner.invoke(app, [str(a) for a in args])
    assert isinstance(out.exception, InputError), out.output
    message = str(out.exception)
    assert "\n" not in message
    return message


def test_cli_errors_are_one_line(egobody, tmp_path):
    """A wrong layout, EgoBody without SMPL models, gated data absent: one line, exit code 2."""
    spec = tmp_path / "eb.json"
    spec.write_text(json.dumps(dict(name="eb", dataset="egobody", sequence=REC, cameras=["master", "sub_1"],
                                    cuts=[2], num_frames=4)))
    (tmp_path / "empty").mkdir()
    assert "--smpl-dir" in invoke_error("dataset", "build", spec, "--data-root", egobody[0], "--out", tmp_path / "o")
    assert "not a data root" in invoke_error("dataset", "list", tmp_path / "empty")
    assert "SMPL_MALE.npz: missing" in invoke_error("dataset", "build", spec, "--data-root", egobody[0], "--out",
                                                      tmp_path / "o", "--smpl-dir", tmp_path / "empty")
    assert not (tmp_path / "o" / "eb" / "ground_truth.npz").exists()
    # Through the real entry point (one subprocess: they are slow on a shared machine).
    out = run_cli("dataset", "build", spec, "--data-root", tmp_path / "empty", "--out", tmp_path / "o")
    lines = out.stderr.strip().splitlines()
    assert out.returncode == 2 and len(lines) == 1, out.stderr
    assert "data_info_release.csv: missing (EgoBody is gated" in lines[0]


def test_smpl_convert_converts_a_chumpy_pickle_and_verifies_it(tmp_path, monkeypatch):
    arrays = build_procedural_smpl()
    source = tmp_path / "SMPL_NEUTRAL.pkl"
    write_chumpy_pickle(arrays, source, monkeypatch)
    target = tmp_path / "SMPL_NEUTRAL.npz"
    out = runner.invoke(app, ["smpl-convert", str(source), str(target), "--json"])
    assert out.exit_code == 0, out.output
    report = json.loads(out.stdout)
    assert report["vertices"] == len(arrays["v_template"]) and report["max_vertex_difference_m"] < 1e-9
    converted = BodyModel(target)
    pose = torch.zeros(1, 69)
    pose[0, 17 * 3] = 0.7
    vertices = converted(torch.zeros(1, 3), pose, torch.zeros(1, 10)).vertices
    assert torch.isfinite(vertices).all() and vertices.shape[-2] == len(arrays["v_template"])
    again = runner.invoke(app, ["smpl-convert", str(source), str(target)])
    assert again.exit_code != 0 and "already exists" in str(again.exception)
    assert runner.invoke(app, ["smpl-convert", str(source), str(target), "--overwrite"]).exit_code == 0


def test_smpl_convert_rejects_what_is_not_an_smpl_pickle(tmp_path):
    (tmp_path / "x.pkl").write_bytes(b"not a pickle")
    assert "x.pkl: cannot be read as a pickle" in invoke_error("smpl-convert", tmp_path / "x.pkl", tmp_path / "x.npz")
    assert not (tmp_path / "x.npz").exists() and not list(tmp_path.glob(".x.*"))
    assert "missing.pkl: no such SMPL model file" in invoke_error("smpl-convert", tmp_path / "missing.pkl",
                                                                  tmp_path / "y.npz")
    assert "written as .npz" in invoke_error("smpl-convert", tmp_path / "x.pkl", tmp_path / "x.pt")
