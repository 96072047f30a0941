import numpy as np
import pytest

from multithumbs.bench import run_scene
from multithumbs.body.model import load_body_model
from multithumbs.method.align import AlignConfig
from multithumbs.method.post import PostConfig
from multithumbs.metrics.evaluate import evaluate
from multithumbs.perception.blazepose_models import missing_models
from multithumbs.pipeline import MethodConfig, run_video, variant_config
from multithumbs.synth.perception import simulate_perception
from multithumbs.synth.scene import SceneConfig, synthesize
from multithumbs.synth.simulated_geometry import simulate_camera_trajectory, simulate_shared_space

FAST = MethodConfig(align=AlignConfig(iterations=(0, 30, 60)), post=PostConfig(iterations=30))


def test_shared_stages_give_each_variant_its_own_result():
    """The bench shares alignment, propagation and post-processing between variants; each variant's scores
    must equal those of running it alone through ``run_video``."""
    config = SceneConfig(num_people=2, num_shots=2, num_frames=12, seed=5, image_size=(180, 320), cut_angle_deg=30)
    variants = ("full", "appearance_only", "no_post", "no_align")
    scores = run_scene(config, variants, FAST)
    body = load_body_model()
    video = synthesize(config, body)
    shots = video.truth.world.shots()
    tracks = simulate_perception(video, body)
    spaces = [simulate_shared_space(video, c) for c in range(len(shots.cut_frames))]
    trajectories = [simulate_camera_trajectory(video, k) for k in range(shots.num_shots)]
    for name in variants:
        alone = evaluate(run_video(shots, tracks, trajectories, spaces, body, variant_config(name, FAST)),
                         video.truth, body)
        for key in ("w_mpjpe", "mpjpe", "accel", "ids"):
            np.testing.assert_allclose(scores.metrics[name][key], alone[key], rtol=1e-6, atol=1e-6, err_msg=name)


def test_perception_through_a_phalp_file_is_what_a_4dhumans_user_gets():
    """The ``phalp`` route writes the simulated tracks as PHALP does and reads them back as ``run`` does:
    the same people and frames (bar the 4 unconfirmed first frames of a track), and 2D keypoints that are the
    mesh's own projections rather than the simulated detector's."""
    import pytest

    from multithumbs.bench import through_phalp_file
    from multithumbs.errors import InputError

    config = SceneConfig(num_people=2, num_shots=2, num_frames=24, seed=5, image_size=(180, 320), cut_angle_deg=30)
    body = load_body_model()
    video = synthesize(config, body)
    direct = simulate_perception(video, body)
    read = through_phalp_file(direct, video, body)
    assert [tr.num_people for tr in read] == [tr.num_people for tr in direct]
    for before, after in zip(direct, read):
        assert after.valid.sum() <= before.valid.sum() and after.valid.sum() >= 0.8 * before.valid.sum()
        both = before.valid & after.valid
        np.testing.assert_allclose(after.betas, before.betas, atol=1e-4)
        # The simulated detector's keypoints are noisy observations; the file's are the mesh reprojected.
        moved = np.abs(after.keypoints2d[both][..., :2] - before.keypoints2d[both][..., :2]).max()
        assert moved > 0.5
        assert after.appearance_valid[both].mean() > 0.5
    with pytest.raises(InputError, match="perception route"):
        run_scene(config, ("full",), FAST, perception="hmr2")


@pytest.mark.slow
@pytest.mark.skipif(bool(missing_models()), reason="BlazePose models not installed (scripts/setup.sh)")
def test_nothing_simulated_inputs_name_their_backends():
    from multithumbs.bench import PIXEL_BACKENDS

    config = SceneConfig(num_people=2, num_shots=2, num_frames=40, seed=5, image_size=(360, 640), cut_angle_deg=30)
    scores = run_scene(config, ["full"], inputs="pixels")
    assert set(scores.backends) == set(PIXEL_BACKENDS)
    assert scores.backends["perception"] == PIXEL_BACKENDS["perception"]
    assert scores.backends["shots"].startswith("scenedetect")
    assert {"shots", "perception_landmarks", "perception_detection", "perception_fitting", "camera_tracking",
            "shared_space"} <= set(scores.stage_seconds)
    assert np.isfinite(scores.metrics["full"]["mpjpe"]) or scores.metrics["full"]["coverage"] == 0


def test_unknown_input_source_is_refused():
    from multithumbs.bench import run_suite
    from multithumbs.errors import InputError

    with pytest.raises(InputError, match="inputs 'rendered'"):
        run_suite([SceneConfig(num_frames=8)], ["full"], inputs="rendered")


def test_one_stage_from_the_pixels_the_others_simulated():
    from multithumbs.bench import BACKENDS

    config = SceneConfig(num_people=2, num_shots=2, num_frames=12, seed=5, image_size=(180, 320), cut_angle_deg=30)
    scores = run_scene(config, ["full"], FAST, inputs="pixels", pixel_stages=("camera_tracking",))
    assert scores.backends["perception"] == BACKENDS["perception"]
    assert scores.backends["shared_space"] == BACKENDS["shared_space"]
    assert not scores.backends["camera_tracking"].startswith("simulated")
    assert scores.backends["shots"] == BACKENDS["shots"]
    assert "perception_landmarks" not in scores.stage_seconds and "camera_tracking" in scores.stage_seconds
    assert np.isfinite(scores.metrics["full"]["w_mpjpe"])


def test_unknown_pixel_stage_is_refused():
    from multithumbs.bench import checked_pixel_stages, run_suite
    from multithumbs.errors import InputError

    assert checked_pixel_stages("shared_space, perception") == ("perception", "shared_space")
    with pytest.raises(InputError, match="pixel stages cameras: expected some of shots, perception"):
        run_suite([SceneConfig(num_frames=8)], ["full"], inputs="pixels", pixel_stages="cameras")
