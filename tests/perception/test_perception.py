"""``load_perception`` and its spec grammar."""

import importlib.util

import numpy as np
import pytest

from multithumbs.errors import InputError
from multithumbs.perception import SpecTerm, load_perception, parse_spec
from multithumbs.perception.phalp import load_phalp
from multithumbs.types import Shots


def test_parse_spec_grammar():
    assert parse_spec("phalp:out/res.pkl") == [SpecTerm("phalp", "out/res.pkl")]
    assert parse_spec("hmr2") == [SpecTerm("hmr2", "")]
    terms = parse_spec("phalp:r.pkl+vitpose+sam:/models/sam-vit-base")
    assert [t.backend for t in terms] == ["phalp", "vitpose", "sam"]
    assert terms[2].argument == "/models/sam-vit-base"
    assert parse_spec("hmr2:checkpoint=/a.ckpt,detector=/b.pkl")[0].options() == {"checkpoint": "/a.ckpt",
                                                                                "detector": "/b.pkl"}


@pytest.mark.parametrize("spec, match", [
    ("", "empty; known backends: blazepose, phalp, hmr2, oracle, vitpose, sam"),
    ("openpose:x", "unknown backend 'openpose'; known backends: blazepose, phalp, hmr2, oracle, vitpose, sam"),
    ("phalp:r.pkl+dino", "unknown backend 'dino'"),
    ("vitpose+sam:/m", "vitpose refines existing tracks; start with a track source"),
    ("phalp:a.pkl+hmr2", "only one track source"),
    ("phalp", "phalp needs a file"),
])
def test_bad_specs(spec, match):
    with pytest.raises(InputError, match=match) as e:
        parse_spec(spec)
    assert "\n" not in str(e.value)


def test_load_perception_phalp(scene, video_file, results_file, noisy_tracks):
    video, shots = scene
    tracks = load_perception(f"phalp:{results_file}", video_file, shots, trust=True)
    assert len(tracks) == shots.num_shots
    for tr, sim in zip(tracks, noisy_tracks):
        assert sorted(tr.track_ids.tolist()) == sorted((sim.track_ids + 1).tolist())  # PHALP's ids count from 1
        assert tr.appearance_valid.sum() >= 0.9 * tr.valid.sum()
    empty = load_perception(f"phalp:{results_file}", video_file, shots, trust=True, appearance=False)
    assert not any(tr.appearance_valid.any() for tr in empty)


def test_load_perception_needs_trust(scene, video_file, results_file):
    with pytest.raises(InputError, match="pass trust=True"):
        load_perception(f"phalp:{results_file}", video_file, scene[1])


def test_load_perception_checks_the_video(scene, video_file, results_file):
    longer = Shots(np.array([8]), 30.0, 20, np.zeros(20))
    with pytest.raises(InputError, match="16 frames but the shots cover 20"):
        load_perception(f"phalp:{results_file}", video_file, longer, trust=True)


@pytest.mark.skipif(importlib.util.find_spec("hmr2") is not None, reason="hmr2 is installed here")
def test_load_perception_hmr2_without_the_package(scene, video_file):
    with pytest.raises(InputError, match="'hmr2': the hmr2 package is not installed"):
        load_perception("hmr2", video_file, scene[1])


def test_load_perception_with_vitpose_and_sam(scene, video_file, results_file, tiny_models, monkeypatch,
                                              one_torch_thread):
    monkeypatch.setenv("HF_HUB_OFFLINE", "1")
    video, shots = scene
    stages = set()
    spec = f"phalp:{results_file}+vitpose:{tiny_models['vitpose']}+sam:{tiny_models['sam']}"
    tracks = load_perception(spec, video_file, shots, trust=True, progress=lambda stage, done, total: stages.add(stage))
    assert stages == {"vitpose", "sam", "appearance"}
    plain = load_phalp(results_file, shots, video.truth.world.image_size, trust=True).tracks
    for a, b in zip(tracks, plain):
        assert not np.array_equal(a.keypoints2d[a.valid], b.keypoints2d[b.valid])
        np.testing.assert_array_equal(a.transl, b.transl)


def test_oracle_spec_checks_the_video_it_is_for(tmp_path):
    from multithumbs.body.model import load_body_model
    from multithumbs.synth.files import write_synthetic
    from multithumbs.synth.scene import SceneConfig, synthesize

    video = synthesize(SceneConfig(num_people=2, num_shots=2, num_frames=6, image_size=(90, 160), seed=4),
                       load_body_model())
    write_synthetic(tmp_path, video)
    shots = video.truth.world.shots()
    tracks = load_perception(f"oracle:{tmp_path / 'ground_truth.npz'}", tmp_path / "video.mp4", shots)
    assert [t.num_people for t in tracks] == [2, 2] and tracks[1].appearance_valid.any()
    other = Shots(np.array([2]), shots.fps, shots.num_frames, np.zeros(shots.num_frames))
    with pytest.raises(InputError, match="cuts"):
        load_perception(f"oracle:{tmp_path / 'ground_truth.npz'}", tmp_path / "video.mp4", other)
