"""`multithumbs run` with no perception argument on OpenCV's sample videos (Debian's opencv-doc, fetched at
test time by the ``opencv_samples`` fixture): the CPU backend finds the people of real footage by itself."""

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from multithumbs.perception.blazepose_models import missing_models

pytestmark = [pytest.mark.slow,
              pytest.mark.skipif(bool(missing_models()), reason="BlazePose models not installed (scripts/setup.sh)")]


def run(video, out, tmp_path):
    env = dict(os.environ, MULTITHUMBS_CACHE=str(tmp_path / "cache"), COLUMNS="80")
    done = subprocess.run([sys.executable, "-m", "multithumbs.cli", "run", str(video), "--out", str(out)],
                          capture_output=True, text=True, env=env, timeout=1800)
    assert done.returncode == 0, done.stderr[-3000:]
    return done


def shots_with_people(out) -> list[set[int]]:
    with np.load(out / "result.npz", allow_pickle=False) as result:
        valid, ids, cuts = result["valid"], result["person_ids"], result["cut_frames"]
    bounds = [0, *cuts.tolist(), valid.shape[1]]
    return [{int(ids[p]) for p in np.flatnonzero(valid[:, a:b].any(axis=1))} for a, b in zip(bounds, bounds[1:])]


def test_megamind_dialogue_has_a_body_on_its_characters_in_every_shot(opencv_samples, tmp_path):
    out = tmp_path / "megamind"
    done = run(opencv_samples / "Megamind.avi", out, tmp_path)
    per_shot = shots_with_people(out)
    assert len(per_shot) == 4 and all(per_shot), per_shot
    report = (out / "report.md").read_text()
    assert "## People" in report and "| perception | blazepose |" in report
    assert "people (global id: shots):" in done.stderr  # notes go to stderr, tables to stdout
    assert json.loads((out / "outputs.json").read_text())


@pytest.mark.timeout(1800)  # 795 frames of pedestrians: 759 s alone on one CPU, over 900 s on a slower one
def test_vtest_pedestrians_are_tracked_without_a_cut(opencv_samples, tmp_path):
    out = tmp_path / "vtest"
    run(opencv_samples / "vtest.avi", out, tmp_path)
    per_shot = shots_with_people(out)
    assert len(per_shot) == 1
    assert len(per_shot[0]) >= 3  # several pedestrians walk through the static view


def test_tree_without_people_says_so_in_one_line_and_writes_a_whole_result(opencv_samples, tmp_path):
    out = tmp_path / "tree"
    done = run(opencv_samples / "tree.avi", out, tmp_path)
    notices = [line for line in done.stderr.splitlines() if line.startswith("no people found")]
    assert len(notices) == 1 and "tree.avi" in notices[0]
    assert shots_with_people(out) == [set()]
    listed = json.loads((out / "outputs.json").read_text())
    assert listed.get("complete", True)
    assert "Nobody was found in any shot" in (out / "report.md").read_text()
