import dataclasses

import numpy as np
import pytest

from multithumbs.errors import InputError
from multithumbs.geometry import reexpress_for_intrinsics
from multithumbs.method.align import AlignConfig
from multithumbs.method.post import PostConfig
from multithumbs.metrics.evaluate import evaluate
from multithumbs.perception.camera import hmr2_intrinsics
from multithumbs.pipeline import VARIANTS, MethodConfig, run_video, variant_config
from multithumbs.synth.perception import true_track_people

FAST = MethodConfig(align=AlignConfig(iterations=(0, 60, 120)), post=PostConfig(iterations=60))


def _run(tiny, body, tracks=None, config=FAST):
    return run_video(tiny.shots, tracks or tiny.tracks, tiny.trajectories, tiny.spaces, body, config)


def test_full_method_links_identities_and_places_people(tiny, body):
    result = _run(tiny, body)
    truth = [true_track_people(tr, tiny.video) for tr in tiny.tracks]
    by_track = {(s, local): g for s, local, g in result.id_map}
    for k, tr in enumerate(tiny.tracks):
        for i, p in enumerate(truth[k]):
            assert by_track[(k, int(tr.track_ids[i]))] == by_track[(0, int(tiny.tracks[0].track_ids[list(truth[0]).index(p)]))]
    scores = evaluate(result, tiny.video.truth, body)
    assert scores["ids"] == 0 and scores["coverage"] > 0.95
    assert scores["w_mpjpe"] < 40 and scores["mpjpe"] < 25
    assert "reid_cost_cut0" in result.diagnostics and result.diagnostics["align_loss_cut0"].size == 180


def test_tracks_in_the_estimators_own_intrinsics_give_the_same_world(tiny, body):
    """4DHumans reports camera-frame translations for its own focal length (perception/camera.py); the method
    re-expresses them for the scene's cameras, so the world does not depend on the estimator's camera."""
    K_hmr = hmr2_intrinsics(tiny.tracks[0].image_size)
    converted = []
    for tr in tiny.tracks:
        pelvis = _pelvis(body, tr)
        moved = reexpress_for_intrinsics(pelvis, tr.K, K_hmr)
        transl = np.where(tr.valid[..., None], moved - (pelvis - tr.transl), 0.0)
        converted.append(dataclasses.replace(tr, K=K_hmr, transl=transl))
    first = tiny.tracks[0].valid.nonzero()
    assert converted[0].transl[first][0, 2] > 10 * tiny.tracks[0].transl[first][0, 2]  # ~30x deeper
    config = variant_config("no_post", FAST)
    a, b = _run(tiny, body, config=config), _run(tiny, body, tracks=converted, config=config)
    np.testing.assert_allclose(b.transl, a.transl, atol=1e-3)
    assert evaluate(b, tiny.video.truth, body)["w_mpjpe"] < 40


def _pelvis(body, tracks):
    rest = body.rest_pelvis(tracks.betas)
    return tracks.transl + rest[:, None]


@pytest.mark.parametrize("variant", VARIANTS)
def test_every_variant_runs(tiny, body, variant):
    result = _run(tiny, body, config=variant_config(variant, FAST))
    assert result.num_frames == tiny.shots.num_frames and result.valid.any()


def test_unknown_variant_is_named():
    with pytest.raises(InputError, match="variant 'bogus'"):
        variant_config("bogus")


def test_nan_in_a_track_is_named(tiny, body):
    bad = dataclasses.replace(tiny.tracks[1], transl=tiny.tracks[1].transl * np.nan)
    with pytest.raises(InputError, match=r"shot 1: PersonTracks.transl"):
        _run(tiny, body, [tiny.tracks[0], bad])


def test_single_frame_person_and_empty_shot_are_documented_outcomes(tiny, body):
    one = tiny.tracks[1]
    valid = np.zeros_like(one.valid)
    valid[0, 2] = True  # the first track is seen in one frame only; the others vanish
    single = dataclasses.replace(one, valid=valid)
    result = _run(tiny, body, [tiny.tracks[0], single])
    assert result.valid.sum(axis=1).min() >= 1
    empty = dataclasses.replace(one, valid=np.zeros_like(one.valid))  # nobody after the cut
    result = _run(tiny, body, [tiny.tracks[0], empty])
    cut = int(tiny.shots.cut_frames[0])
    assert not result.valid[:, cut:].any() and result.valid[:, :cut].any()


def test_mismatched_inputs_are_named(tiny, body):
    with pytest.raises(InputError, match="shared spaces"):
        run_video(tiny.shots, tiny.tracks, tiny.trajectories, [], body, FAST)
    with pytest.raises(InputError, match="track sets"):
        run_video(tiny.shots, tiny.tracks[:1], tiny.trajectories, tiny.spaces, body, FAST)


def test_a_video_without_a_cut_is_one_shot_in_its_own_frame():
    """No cut (e.g. the detector found none in a short clip): no shared space to align, the world is the
    shot's own SLAM frame; the chain runs instead of failing on a missing boundary."""
    from multithumbs.body.model import load_body_model
    from multithumbs.metrics.evaluate import evaluate
    from multithumbs.pipeline import MethodConfig, run_video
    from multithumbs.synth.perception import simulate_perception
    from multithumbs.synth.scene import SceneConfig, synthesize
    from multithumbs.synth.simulated_geometry import simulate_camera_trajectory

    body = load_body_model()
    video = synthesize(SceneConfig(num_people=2, num_shots=1, num_frames=10, seed=5, image_size=(180, 320)), body)
    shots = video.truth.world.shots()
    result = run_video(shots, simulate_perception(video, body), [simulate_camera_trajectory(video, 0)], [], body,
                       MethodConfig())
    scores = evaluate(result, video.truth, body)
    assert scores["ids"] == 0 and scores["coverage"] > 0.9 and scores["mpjpe"] < 60.0
