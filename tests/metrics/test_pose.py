import numpy as np
import pytest

from multithumbs.errors import InputError
from multithumbs.metrics.alignment import apply_similarity
from multithumbs.metrics.pose import (
    accel, accel_world, foot_sliding_against_truth, mpjpe, mpvpe, pa_mpjpe, w_mpjpe, wa_mpjpe,
)
from tests.metrics import reference
from tests.metrics.conftest import random_similarity


def _tracks(rng, p=2, t=30, n=24):
    """Smooth random joint tracks ``(p, t, n, 3)``."""
    base = rng.normal(size=(p, 1, n, 3)) * 0.3
    drift = np.cumsum(rng.normal(size=(p, t, 1, 3)) * 0.02, axis=1)
    return base + drift


def _sim_apply(sim, points):
    return apply_similarity(sim, points.reshape(-1, 3)).reshape(points.shape)


def test_perfect_prediction_has_zero_error():
    rng = np.random.default_rng(0)
    joints = _tracks(rng)
    verts = np.repeat(joints, 3, axis=2) + 0.01
    valid = np.ones(joints.shape[:2], bool)
    for samples in (mpjpe(joints, joints, valid), mpjpe(joints, joints, valid, root_align=False),
                    pa_mpjpe(joints, joints, valid), w_mpjpe(joints, joints, valid),
                    wa_mpjpe(joints, joints, valid), w_mpjpe(joints, joints, valid, chunk=None),
                    mpvpe(verts, verts, joints, joints, valid), accel(joints, joints, valid, 30.0),
                    accel_world(joints, joints, valid)):
        assert samples.mean() == pytest.approx(0.0, abs=1e-8)


def test_world_mpjpe_invariant_to_global_similarity():
    rng = np.random.default_rng(1)
    true = _tracks(rng)
    valid = np.ones(true.shape[:2], bool)
    valid[0, :3] = False  # the first-two fit must skip invalid frames
    pred = _sim_apply(random_similarity(rng), true)
    assert w_mpjpe(pred, true, valid).mean() < 1e-6
    assert wa_mpjpe(pred, true, valid).mean() < 1e-6
    assert mpjpe(pred, true, valid).mean() > 1.0  # without alignment the error is large


def test_w_mpjpe_hand_computed():
    # One person, three frames: the first two are exact (the fit is the identity), frame 2 is 10 mm off.
    rng = np.random.default_rng(2)
    true = rng.normal(size=(1, 3, 24, 3))
    pred = true.copy()
    pred[0, 2, :, 0] += 0.010
    valid = np.ones((1, 3), bool)
    samples = w_mpjpe(pred, true, valid)
    np.testing.assert_allclose(samples.values[0], [0.0, 0.0, 10.0], atol=1e-9)
    assert samples.mean() == pytest.approx(10.0 / 3)
    # WA fits all frames and spreads the offset over every frame.
    assert np.all(wa_mpjpe(pred, true, valid).values[0, :2] > 1.0)


def test_w_mpjpe_chunk_100_realigns():
    rng = np.random.default_rng(3)
    true = _tracks(rng, p=1, t=250)
    pred = true.copy()
    for start in (0, 100, 200):  # each 100-frame chunk under its own similarity
        pred[:, start:start + 100] = _sim_apply(random_similarity(rng), true[:, start:start + 100])
    valid = np.ones((1, 250), bool)
    assert w_mpjpe(pred, true, valid).mean() < 1e-6  # chunks of 100 by default
    assert w_mpjpe(pred, true, valid, chunk=None).mean() > 100.0


def test_pa_mpjpe_invariant_to_per_frame_similarity():
    rng = np.random.default_rng(4)
    true = _tracks(rng, p=2, t=10)
    pred = true + rng.normal(size=true.shape) * 0.02
    valid = np.ones((2, 10), bool)
    valid[1, 4] = False
    base = pa_mpjpe(pred, true, valid)
    moved = apply_similarity(random_similarity(rng, (2, 10)), pred)
    assert base.mean() > 1.0
    np.testing.assert_allclose(pa_mpjpe(moved, true, valid).scored, base.scored, rtol=1e-9)


def test_mpjpe_root_aligned_invariant_to_translation():
    rng = np.random.default_rng(5)
    true = _tracks(rng)
    pred = true + rng.normal(size=true.shape) * 0.02
    valid = np.ones(true.shape[:2], bool)
    shift = np.array([0.3, -0.4, 0.0])  # 0.5 m
    base = mpjpe(pred, true, valid).mean()
    assert mpjpe(pred + shift, true, valid).mean() == pytest.approx(base, rel=1e-12)
    assert mpjpe(true + shift, true, valid, root_align=False).mean() == pytest.approx(500.0)
    verts, verts_true = np.repeat(pred, 2, axis=2), np.repeat(true, 2, axis=2)
    assert mpvpe(verts + shift, verts_true, pred + shift, true, valid).mean() == pytest.approx(
        mpvpe(verts, verts_true, pred, true, valid).mean(), rel=1e-12)
    assert mpvpe(verts_true + shift, verts_true, true + shift, true, valid, root_align=False).mean() == \
        pytest.approx(500.0)


def test_unscored_frames_do_not_count():
    rng = np.random.default_rng(6)
    true = _tracks(rng)
    pred = true.copy()
    pred[0, 5] += 10.0
    valid = np.ones(true.shape[:2], bool)
    assert mpjpe(pred, true, valid, root_align=False).mean() > 100.0
    valid[0, 5] = False
    assert mpjpe(pred, true, valid, root_align=False).mean() == 0.0


def test_accel_zero_for_constant_velocity():
    t = np.arange(20.0)[None, :, None, None]
    start = np.random.default_rng(7).normal(size=(1, 1, 24, 3))
    pred = start + t * np.array([0.05, 0.01, 0.0])
    true = start + t * np.array([-0.02, 0.03, 0.01])  # another constant velocity: also zero acceleration
    valid = np.ones((1, 20), bool)
    for metric in (lambda a, b, v: accel(a, b, v, 30.0), accel_world):
        assert metric(pred, pred, valid).mean() == pytest.approx(0.0, abs=1e-9)
        assert metric(pred, true, valid).mean() == pytest.approx(0.0, abs=1e-9)


def test_accel_world_include_cuts_on_a_jump():
    rng = np.random.default_rng(8)
    true = _tracks(rng, p=1, t=12)
    pred = true.copy()
    pred[:, 6:] += np.array([1.0, 0.0, 0.0])  # a 1 m jump at the cut
    valid = np.ones((1, 12), bool)
    with_cuts = accel_world(pred, true, valid, [6], include_cuts=True)
    without = accel_world(pred, true, valid, [6], include_cuts=False)
    # Triplets centred on frames 5 and 6 see the jump (+d, then -d): 1000 mm each over 10 triplets.
    assert with_cuts.mean() == pytest.approx(2000.0 / 10)
    assert without.mean() == pytest.approx(0.0, abs=1e-9)
    assert without.count == 8


def test_foot_sliding_against_truth_uses_raw_feet_and_keeps_cut_pairs():
    t = 10
    true = np.zeros((1, t, 2, 3))
    true[0, :, 1, 0] = 0.05 * np.arange(t)  # second foot swings: never in contact
    planted = true.copy()
    sliding = true.copy()
    sliding[0, :, 0, 0] = 0.005 * np.arange(t)  # 5 mm per frame while the true foot rests
    valid = np.ones((1, t), bool)
    assert foot_sliding_against_truth(planted, true, valid).mean() == pytest.approx(0.0)
    fs = foot_sliding_against_truth(sliding, true, valid)
    assert fs.mean() == pytest.approx(5.0)
    assert fs.count == t - 1  # every pair, a cut's too (GVHMR keeps them)
    # As predicted, not aligned: a world 1.5 times too large slides 1.5 times as far.
    assert foot_sliding_against_truth(1.5 * sliding, true, valid).mean() == pytest.approx(7.5)
    # The truth against itself slides exactly zero where it rests.
    assert foot_sliding_against_truth(true, true, valid).mean() == pytest.approx(0.0)


def test_foot_sliding_against_truth_over_compressed_frames_hand_computed():
    # Frames 3 and 4 missing: pairs (0,1), (1,2), (2,5), (5,6), (6,7); the true foot rests throughout.
    true = np.zeros((1, 8, 1, 3))
    pred = np.zeros((1, 8, 1, 3))
    pred[0, :, 0, 0] = 0.001 * np.arange(8)  # 1 mm per frame
    valid = np.ones((1, 8), bool)
    valid[0, 3:5] = False
    fs = foot_sliding_against_truth(pred, true, valid)
    np.testing.assert_allclose(np.sort(fs.scored), [1.0, 1.0, 1.0, 1.0, 3.0])
    np.testing.assert_allclose(fs.scored, reference.foot_sliding_values(pred, true, valid))


def test_w_mpjpe_chunks_over_valid_frames_hand_computed():
    # 250 frames, frames 50-99 missing: 200 valid frames, chunks (compressed) [0-49, 100-149] and
    # [150-249]. The prediction is exact before frame 150 and 0.1 m off in x from frame 150 on.
    rng = np.random.default_rng(9)
    true = _tracks(rng, p=1, t=250)
    pred = true.copy()
    pred[0, 150:, :, 0] += 0.1
    valid = np.ones((1, 250), bool)
    valid[0, 50:100] = False
    # Compressed chunks each hold one offset: zero error.
    assert w_mpjpe(pred, true, valid).mean() == pytest.approx(0.0, abs=1e-6)
    assert wa_mpjpe(pred, true, valid).mean() == pytest.approx(0.0, abs=1e-6)
    # Chunks by frame index ([100, 200) mixes both) would give 100 mm on 50 of 200 frames: 25 mm.
    # The whole track: the first two frames fix the alignment, 100 of 200 frames are 100 mm off.
    assert w_mpjpe(pred, true, valid, chunk=None).mean() == pytest.approx(50.0, rel=1e-9)


def test_w_mpjpe_last_chunk_of_one_frame():
    # 201 valid frames: the third chunk is one frame, fitted on itself alone.
    rng = np.random.default_rng(10)
    true = _tracks(rng, p=1, t=201)
    pred = true + rng.normal(size=true.shape) * 0.01
    pred[0, 200] = _sim_apply(random_similarity(rng), true[0, 200])
    valid = np.ones((1, 201), bool)
    samples = w_mpjpe(pred, true, valid)
    assert samples.values[0, 200] == pytest.approx(0.0, abs=1e-6)
    np.testing.assert_allclose(samples.scored, reference.world_errors(pred, true, valid), rtol=1e-9, atol=1e-9)


def test_accel_hand_computed_over_compressed_frames():
    # Joint 5 moves as c * t^2 in camera frame, the hips stay: pelvis alignment keeps it. Frames 3, 4
    # missing: compressed frames 0, 1, 2, 5, 6, 7, whose second differences of c * t^2 are
    # (0 - 2 + 4) c, (1 - 8 + 25) c, (4 - 50 + 36) c, (25 - 72 + 49) c = 2c, 18c, -10c, 2c.
    c, fps = 0.001, 30.0
    true = np.zeros((1, 8, 24, 3))
    pred = true.copy()
    pred[0, :, 5, 1] = c * np.arange(8.0) ** 2
    valid = np.ones((1, 8), bool)
    valid[0, 3:5] = False
    samples = accel(pred, true, valid, fps)
    expected = np.array([2.0, 18.0, 10.0, 2.0]) * c * fps ** 2 / 24  # one joint of 24, m/s^2
    np.testing.assert_allclose(np.sort(samples.scored), np.sort(expected), rtol=1e-12)
    # A common translation is removed by the pelvis alignment.
    moved = pred + (np.arange(8.0) ** 3)[None, :, None, None] * np.array([0.01, 0.0, 0.0])
    np.testing.assert_allclose(accel(moved, true, valid, fps).scored, samples.scored, atol=1e-9)
    with pytest.raises(InputError, match="fps"):
        accel(pred, true, valid, 0.0)


def test_headline_metrics_equal_the_reference_protocol_on_perturbed_tracks():
    # Noise, a Sim(3) offset per person, drift, missing frames, tracks long enough for three chunks.
    rng = np.random.default_rng(11)
    p, t = 3, 260
    true = _tracks(rng, p=p, t=t)
    pred = true + rng.normal(size=true.shape) * 0.02
    pred += np.linspace(0, 0.4, t)[None, :, None, None] * np.array([1.0, 0.0, 0.5])
    for person in range(p):
        pred[person] = _sim_apply(random_similarity(rng), pred[person])
    valid = rng.random((p, t)) > 0.15
    valid[1, 40:90] = False
    for first_two, metric in ((True, w_mpjpe), (False, wa_mpjpe)):
        for chunk in (100, None):
            ours = metric(pred, true, valid, chunk=chunk)
            ref = reference.world_errors(pred, true, valid, chunk, first_two)
            assert ours.count == len(ref)
            assert ours.mean() == pytest.approx(ref.mean(), rel=1e-6)
    ours = accel(pred, true, valid, 30.0)
    ref = reference.accel_errors(pred, true, valid, 30.0)
    assert ours.count == len(ref) and ours.mean() == pytest.approx(ref.mean(), rel=1e-6)
    feet, true_feet = pred[:, :, [7, 8, 10, 11]], true[:, :, [7, 8, 10, 11]]
    ours = foot_sliding_against_truth(feet, true_feet, valid)
    ref = reference.foot_sliding_values(feet, true_feet, valid)
    assert ours.count == len(ref) > 0 and ours.mean() == pytest.approx(ref.mean(), rel=1e-6)


def test_shape_mismatch_is_an_input_error():
    with pytest.raises(InputError, match="pred"):
        mpjpe(np.zeros((1, 2, 24, 3)), np.zeros((1, 3, 24, 3)), np.ones((1, 2), bool))
    with pytest.raises(InputError, match="valid"):
        mpjpe(np.zeros((1, 2, 24, 3)), np.zeros((1, 2, 24, 3)), np.ones((2, 2), bool))
