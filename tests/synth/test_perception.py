
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from multithumbs.appearance import appearance_dissimilarity, mean_descriptor
from multithumbs.geometry import world_to_camera
from multithumbs.synth.perception import NO_NOISE, PerceptionNoise, simulate_perception, true_track_people
from multithumbs.synth.scene import SceneConfig, synthesize


@pytest.fixture(scope="module")
def video(body):
    config = SceneConfig(num_people=3, num_shots=2, num_frames=16, seed=21, image_size=(240, 426),
                         dressed_alike=((0, 1),))
    return synthesize(config, body)


def test_perfect_perception_is_the_truth_in_each_camera_frame(video, body):
    tracks = simulate_perception(video, body, NO_NOISE)
    world = video.truth.world
    assert [tr.shot_index for tr in tracks] == [0, 1]
    for tr in tracks:
        people = true_track_people(tr, video)
        np.testing.assert_array_equal(tr.track_ids, people)  # ids not shuffled without noise
        f0 = tr.start_frame
        for i, p in enumerate(people):
            f = f0 + int(np.argmax(tr.valid[i]))
            j = f - f0
            # Joints from the camera-frame parameters equal the true joints in camera coordinates.
            cam = body.forward(tr.global_orient[i, j], tr.body_pose[i, j], tr.betas[i], tr.transl[i, j]).joints.numpy()
            true = body.forward(world.global_orient[p, f], world.body_pose[p, f], world.betas[p], world.transl[p, f])
            np.testing.assert_allclose(cam, world_to_camera(true.joints.double().numpy(), world.R[f], world.t[f]),
                                       atol=2e-4)


def test_noisy_perception_shuffles_ids_and_corrupts_like_an_estimator(video, body):
    clean = simulate_perception(video, body, NO_NOISE)
    noisy = simulate_perception(video, body, PerceptionNoise(), seed=1)
    ids = [set(tr.track_ids.tolist()) for tr in noisy]
    assert ids[0] != set(range(3)) or ids[1] != set(range(3))
    for c, n in zip(clean, noisy):
        order_c, order_n = true_track_people(c, video), true_track_people(n, video)
        for i, p in enumerate(order_n):
            if p < 0 or p not in order_c:
                continue
            ci = int(np.nonzero(order_c == p)[0][0])
            both = n.valid[i] & c.valid[ci]
            angle = np.linalg.norm((Rotation.from_rotvec(n.body_pose[i, both].reshape(-1, 3)).inv()
                                    * Rotation.from_rotvec(c.body_pose[ci, both].reshape(-1, 3))).as_rotvec(), axis=1)
            assert 1.0 < np.degrees(angle).mean() < 15.0  # a few degrees, as estimators err
            # depth error along the ray keeps the 2D position of the pelvis
            ratio = np.linalg.norm(n.transl[i, both], axis=-1).mean() / np.linalg.norm(c.transl[ci, both], axis=-1).mean()
            assert 0.6 < ratio < 1.6
            kp_err = np.linalg.norm(n.keypoints2d[i, both, :, :2] - c.keypoints2d[ci, both, :, :2], axis=-1)
            assert 0.5 < np.median(kp_err) < 10


def test_appearance_comes_from_pixels_and_tells_clothes_apart(video, body):
    tracks = simulate_perception(video, body, NO_NOISE)
    tr = tracks[0]
    people = true_track_people(tr, video)
    desc = {int(p): mean_descriptor(tr.appearance[i], tr.appearance_valid[i]) for i, p in enumerate(people)}
    assert tr.appearance_valid.any()
    alike = appearance_dissimilarity(desc[0], desc[1])
    different = min(appearance_dissimilarity(desc[0], desc[2]), appearance_dissimilarity(desc[1], desc[2]))
    assert alike < different
    # The same person seen in the other shot, from another viewpoint, stays close.
    other = tracks[1]
    people_b = true_track_people(other, video)
    i2 = int(np.nonzero(people_b == 2)[0][0])
    across = appearance_dissimilarity(desc[2], mean_descriptor(other.appearance[i2], other.appearance_valid[i2]))
    assert across < different
