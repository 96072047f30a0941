import numpy as np
import pytest

from multithumbs.errors import InputError
from multithumbs.geometry import camera_centre
from multithumbs.metrics.alignment import apply_similarity, fit_similarity
from multithumbs.scene.tracking import track_camera
from tests.scene.conftest import rotation_error_deg


def test_static_shot_is_detected(static_clip):
    (a, b) = static_clip.world.shots().ranges[0]
    video = static_clip.video
    traj = track_camera(video.frames[a:b], static_clip.world.K[a], video.instance[a:b] >= 0, 0, a)
    assert traj.source == "static" and traj.num_frames == b - a and traj.start_frame == a
    np.testing.assert_allclose(traj.R, np.tile(np.eye(3), (b - a, 1, 1)))
    np.testing.assert_allclose(traj.t, 0)


def test_moving_shot_trajectory_accuracy(moving_clip):
    w, video = moving_clip.world, moving_clip.video
    for k, (a, b) in enumerate(w.shots().ranges):
        traj = track_camera(video.frames[a:b], w.K[a], video.instance[a:b] >= 0, k, a)
        assert traj.source == "pycolmap" and traj.shot_index == k
        np.testing.assert_allclose(traj.R[0], np.eye(3), atol=1e-9)
        true_c = camera_centre(w.R[a:b], w.t[a:b])
        est_c = camera_centre(traj.R, traj.t)
        # ATE after Sim(3) (well defined for a straight dolly: the optimum's residual is unique).
        sim, _ = fit_similarity(est_c, true_c)
        ate = np.sqrt((np.linalg.norm(apply_similarity(sim, est_c) - true_c, axis=1) ** 2).mean())
        length = np.linalg.norm(np.diff(true_c, axis=0), axis=1).sum()
        assert ate < 0.02 * length
        for f in range(b - a):
            assert rotation_error_deg(traj.R[f] @ traj.R[0].T, w.R[a + f] @ w.R[a].T) < 1.5
        assert traj.points is not None and len(traj.points) > 50


def test_single_frame_black_and_bad_inputs(static_clip):
    frame = static_clip.video.frames[:1]
    K = static_clip.world.K[0]
    assert track_camera(frame, K).source == "static"
    black = np.zeros((6, 40, 60, 3), np.uint8)
    assert track_camera(black, K).source == "static"
    with pytest.raises(InputError, match="frames"):
        track_camera(np.zeros((3, 10, 10), np.uint8), K)
    with pytest.raises(InputError, match="K"):
        track_camera(black, np.eye(2))
    with pytest.raises(InputError, match="person_masks"):
        track_camera(black, K, np.zeros((2, 40, 60), bool))
    with pytest.raises(InputError, match="no frames"):
        track_camera(np.zeros((0, 40, 60, 3), np.uint8), K)
