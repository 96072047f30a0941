import numpy as np

from multithumbs.bench import run_scene
from multithumbs.body.model import load_body_model
from multithumbs.method.align import AlignConfig
from multithumbs.method.post import PostConfig
from multithumbs.metrics.evaluate import evaluate
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
