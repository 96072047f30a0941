import numpy as np
import pytest

from multithumbs.errors import InputError
from multithumbs.metrics.alignment import (
    Samples, apply_similarity, apply_track_similarities, fit_similarity, pair_people, pelvis,
    ValidFrames, track_similarities, window_mask,
)
from tests.metrics.conftest import random_similarity


def test_umeyama_scale_matches_closed_form():
    rng = np.random.default_rng(1)
    x = rng.normal(size=(30, 3))
    y = 1.7 * x @ rng.normal(size=(3, 3)) + rng.normal(size=(30, 3)) * 0.1  # not an exact similarity
    mx, my = x.mean(0), y.mean(0)
    cov = (y - my).T @ (x - mx) / len(x)
    u, d, vt = np.linalg.svd(cov)
    s_fix = np.diag([1.0, 1.0, np.sign(np.linalg.det(u) * np.linalg.det(vt))])
    var_x = np.mean(np.sum((x - mx) ** 2, axis=-1))
    sim, fitted = fit_similarity(x, y)
    scale, rotation, translation = sim.numpy()
    assert fitted
    np.testing.assert_allclose(scale, np.trace(np.diag(d) @ s_fix) / var_x, rtol=1e-10)
    np.testing.assert_allclose(rotation, u @ s_fix @ vt, atol=1e-10)
    np.testing.assert_allclose(translation, my - scale * rotation @ mx, atol=1e-10)


def test_fit_similarity_recovers_and_ignores_masked_points():
    rng = np.random.default_rng(2)
    truth = random_similarity(rng)
    x = rng.normal(size=(20, 3))
    y = apply_similarity(truth, x)
    y[15:] = 1e3 * rng.normal(size=(5, 3))  # garbage, masked out
    mask = np.arange(20) < 15
    sim, _ = fit_similarity(x, y, mask)
    np.testing.assert_allclose(apply_similarity(sim, x)[:15], y[:15], atol=1e-9)
    with pytest.raises(AssertionError):
        np.testing.assert_allclose(apply_similarity(fit_similarity(x, y)[0], x)[:15], y[:15], atol=1e-3)


def test_fit_similarity_without_points_is_identity():
    points = np.random.default_rng(0).normal(size=(2, 5, 3))
    sim, fitted = fit_similarity(points, points + 1.0, np.array([[True] * 5, [False] * 5]))
    assert fitted.tolist() == [True, False]
    scale, rotation, translation = sim.numpy()
    assert scale[1] == pytest.approx(1.0) and np.allclose(rotation[1], np.eye(3)) and np.allclose(translation[1], 0)
    np.testing.assert_allclose(translation[0], [1, 1, 1], atol=1e-12)


def test_track_similarities_first_two_uses_only_first_two_valid_frames():
    rng = np.random.default_rng(3)
    true = rng.normal(size=(1, 6, 24, 3))
    sim = random_similarity(rng)
    pred = apply_similarity(sim.inverse(), true.reshape(1, -1, 3)).reshape(true.shape)
    pred[0, 4:] += 5.0  # later frames disagree: the first-two fit must not see them
    valid = np.array([[False, True, True, True, True, True]])
    fitted_sim, fitted = track_similarities(pred, true, valid, "first_two")
    aligned = apply_track_similarities(fitted_sim, pred, valid)
    np.testing.assert_allclose(aligned[0, 1:4], true[0, 1:4], atol=1e-9)
    # The whole-track fit spreads the disagreement over every frame.
    all_sim, _ = track_similarities(pred, true, valid, "all")
    assert np.abs(apply_track_similarities(all_sim, pred, valid)[0, 1] - true[0, 1]).max() > 1e-3
    assert fitted.shape == (1, 1)


def test_track_similarities_chunks():
    rng = np.random.default_rng(4)
    true = rng.normal(size=(2, 25, 4, 3))
    pred = true.copy()
    pred[:, 10:20] += 1.0  # a different offset per 10-frame chunk
    pred[:, 20:] *= 2.0
    valid = np.ones((2, 25), bool)
    sim, fitted = track_similarities(pred, true, valid, "all", chunk=10)
    assert fitted.shape == (2, 3)
    np.testing.assert_allclose(apply_track_similarities(sim, pred, valid, chunk=10), true, atol=1e-9)
    with pytest.raises(InputError, match="chunk"):
        track_similarities(pred, true, valid, "all", chunk=0)


def test_track_similarities_chunk_the_valid_frames_not_the_frame_axis():
    # Frames 3-6 missing: the 10-frame chunks hold frames 0-2, 7-13 and 14-19 (compressed).
    rng = np.random.default_rng(5)
    true = rng.normal(size=(1, 20, 4, 3))
    valid = np.ones((1, 20), bool)
    valid[0, 3:7] = False
    pred = true.copy()
    pred[0, 14:] += 1.0
    sim, fitted = track_similarities(pred, true, valid, "all", chunk=10)
    assert fitted.tolist() == [[True, True]]
    aligned = apply_track_similarities(sim, pred, valid, chunk=10)
    np.testing.assert_allclose(aligned[valid], true[valid], atol=1e-9)


def test_valid_frames_pack_and_unpack():
    valid = np.array([[True, False, True, True], [False, False, True, False]])
    packing = ValidFrames.of(valid)
    assert packing.valid.tolist() == [[True, True, True, False], [True, False, False, False]]
    assert packing.frames.tolist() == [[0, 2, 3, -1], [2, -1, -1, -1]]
    series = np.arange(8.0).reshape(2, 4, 1)
    assert packing.pack(series)[..., 0].tolist() == [[0, 2, 3, 1], [6, 4, 5, 7]]
    np.testing.assert_array_equal(packing.unpack(packing.pack(series)), series)


def test_window_mask_with_and_without_cuts():
    valid = np.array([True, True, True, True, False, True, True, True])
    np.testing.assert_array_equal(window_mask(valid, 3), [1, 1, 0, 0, 0, 1])
    # Cut at frame 2: windows [0..2] and [1..3] span it.
    np.testing.assert_array_equal(window_mask(valid, 3, [2], include_cuts=False), [0, 0, 0, 0, 0, 1])
    np.testing.assert_array_equal(window_mask(valid, 2, [6], include_cuts=False), [1, 1, 1, 0, 0, 0, 1])
    # Packed entries: the video frame of each entry decides the shot.
    frames = np.array([0, 1, 2, 3, 5, 6, 7, -1])
    packed = np.array([True] * 7 + [False])
    np.testing.assert_array_equal(window_mask(packed, 2, [5], include_cuts=False, frames=frames),
                                  [1, 1, 1, 0, 1, 1, 0])
    assert window_mask(valid[:2], 3).shape == (0,)


def test_pelvis_is_mean_of_hips():
    joints = np.zeros((24, 3))
    joints[1], joints[2], joints[0] = [1, 0, 0], [3, 2, 0], [9, 9, 9]
    np.testing.assert_allclose(pelvis(joints), [2, 1, 0])


def test_pair_people_hand_case():
    # Two true people, three predictions; prediction 1 stands for true 0, prediction 2 for true 1,
    # prediction 0 is never co-visible with anyone.
    t = 4
    true_roots = np.zeros((2, t, 3))
    true_roots[1, :, 0] = 5.0
    pred_roots = np.zeros((3, t, 3))
    pred_roots[0, :, 0] = 0.1
    pred_roots[1, :, 0] = 0.2
    pred_roots[2, :, 0] = 5.3
    true_visible = np.ones((2, t), bool)
    pred_valid = np.array([[False] * 4, [True, True, False, True], [True] * 4])
    pairing = pair_people(pred_roots, pred_valid, true_roots, true_visible)
    assert pairing.pred_index.tolist() == [1, 2]
    np.testing.assert_allclose(pairing.root_distance[0, 1], 0.2)
    np.testing.assert_allclose(pairing.root_distance[1, 2], 0.3)
    assert pairing.covisible[0, 0] == 0
    np.testing.assert_array_equal(pairing.scored[0], [True, True, False, True])
    assert pairing.coverage == pytest.approx(7 / 8)
    gathered = pairing.gather(pred_roots)
    np.testing.assert_allclose(gathered[:, 0, 0], [0.2, 5.3])


def test_pair_people_unpaired_true_person_counts_as_missed():
    true_roots = np.zeros((2, 3, 3))
    pred_roots = np.zeros((1, 3, 3))
    pairing = pair_people(pred_roots, np.ones((1, 3), bool), true_roots, np.ones((2, 3), bool))
    assert sorted(pairing.pred_index.tolist()) == [-1, 0]
    assert pairing.coverage == pytest.approx(0.5)
    empty = pair_people(np.zeros((0, 3, 3)), np.zeros((0, 3), bool), true_roots, np.ones((2, 3), bool))
    assert empty.pred_index.tolist() == [-1, -1] and empty.coverage == 0.0


def test_samples_mean_and_pooling():
    a = Samples(np.array([1.0, 2.0, 99.0]), np.array([True, True, False]))
    b = Samples(np.array([[4.0]]), np.array([[True]]))
    assert a.mean() == pytest.approx(1.5)
    assert Samples.concatenate([a, b]).mean() == pytest.approx(7 / 3)  # frame-weighted, not (1.5 + 4) / 2
    assert np.isnan(Samples(np.zeros(2), np.zeros(2, bool)).mean())
    with pytest.raises(InputError, match="mask"):
        Samples(np.zeros(2), np.zeros(3, bool))
