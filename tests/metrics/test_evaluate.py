from dataclasses import replace

import numpy as np
import pytest
import torch

from multithumbs.errors import InputError
from multithumbs.geometry import axis_angle_to_matrix, matrix_to_axis_angle, transform_cameras
from multithumbs.metrics.evaluate import evaluate, evaluate_sequences
from multithumbs.types import WorldResult
from tests.metrics.conftest import random_similarity

ERROR_KEYS = ("w_mpjpe", "wa_mpjpe", "mpjpe", "pa_mpjpe", "mpvpe", "accel", "mpjpe_world", "mpvpe_world",
              "w_mpjpe_track", "wa_mpjpe_track", "accel_world")
REQUIRED_KEYS = {"w_mpjpe", "wa_mpjpe", "mpjpe", "pa_mpjpe", "mpvpe", "accel", "ate", "ids", "pck", "jitter",
                 "fs", "coverage", "ids_per_cut", "pck_005", "ate_mean", "ate_fallback", "mpjpe_world",
                 "mpvpe_world", "w_mpjpe_track", "wa_mpjpe_track", "accel_world", "fs_gt", "ids_total",
                 "ids_at_cuts", "ids_within_shots", "ids_per_sequence", "ate_per_sequence", "ate_alignment",
                 "fs_truth", "id_switch_events", "options"}


def _move_world(world: WorldResult, rng: np.random.Generator) -> WorldResult:
    """The same reconstruction expressed in another world frame (random SE(3): SMPL bodies cannot scale)."""
    sim = random_similarity(rng, with_scale=False)
    _, rotation, translation = sim.numpy()
    orient = matrix_to_axis_angle(rotation @ axis_angle_to_matrix(world.global_orient))
    R, t = transform_cameras(sim, torch.from_numpy(world.R), torch.from_numpy(world.t))
    # The fake body rotates about joint 0 at ``transl``, so the translation moves as a point.
    return replace(world, global_orient=orient, transl=world.transl @ rotation.T + translation,
                   R=R.numpy(), t=t.numpy())


def _splice(world: WorldResult, sources: list[list[int]], cut: int) -> WorldResult:
    """Predicted people built from true people: ``sources[k] = [before-cut source, after-cut source]``
    (-1 for absent)."""
    people = len(sources)
    fields = {name: np.zeros((people, *getattr(world, name).shape[1:]))
              for name in ("global_orient", "body_pose", "transl")}
    valid = np.zeros((people, world.num_frames), bool)
    betas = np.zeros((people, 10))
    keypoints = np.zeros((people, *world.keypoints2d.shape[1:]))
    for k, pair in enumerate(sources):
        for side, src in enumerate(pair):
            if src < 0:
                continue
            frames = slice(0, cut) if side == 0 else slice(cut, None)
            for name in fields:
                fields[name][k, frames] = getattr(world, name)[src, frames]
            keypoints[k, frames] = world.keypoints2d[src, frames]
            valid[k, frames] = True
            betas[k] = world.betas[src]
    return replace(world, person_ids=np.arange(people) + 10, betas=betas, valid=valid, keypoints2d=keypoints,
                   id_map=np.zeros((0, 3), np.int64), **fields)


def test_ground_truth_scores_zero(scene, body_model):
    truth = scene()
    report = evaluate(truth.world, truth, body_model)
    assert REQUIRED_KEYS <= set(report)
    for key in ERROR_KEYS:
        assert report[key] == pytest.approx(0.0, abs=1e-6), key
    assert report["ate"] == pytest.approx(0.0, abs=1e-9) and not report["ate_fallback"]
    assert report["ids"] == 0 and report["coverage"] == 1.0
    assert report["pck"] == pytest.approx(100.0)
    assert np.isfinite(report["jitter"]) and np.isfinite(report["fs"])
    assert report["options"]["chunk"] == 100 and report["options"]["min_iou"] == 0.5
    assert report["ate_alignment"] == ["sim3_camera_centres"] and report["ids_total"] == 0


def test_global_rigid_motion_of_the_whole_prediction_changes_nothing(scene, body_model):
    truth = scene()
    moved = _move_world(truth.world, np.random.default_rng(5))
    report = evaluate(moved, truth, body_model)
    for key in ERROR_KEYS:
        assert report[key] == pytest.approx(0.0, abs=1e-6), key
    assert report["ate"] == pytest.approx(0.0, abs=1e-9)
    assert report["ids"] == 0 and report["pck"] == pytest.approx(100.0)
    assert report["jitter"] == pytest.approx(evaluate(truth.world, truth, body_model)["jitter"], rel=1e-9)


def test_swapped_identities_at_the_cut(scene, body_model):
    truth = scene()
    cut = int(truth.world.cut_frames[0])
    swapped = _splice(truth.world, [[0, 1], [1, 0]], cut)
    report = evaluate(swapped, truth, body_model)
    assert report["ids"] == 2 and report["ids_per_cut"] == 2.0
    assert report["ids_at_cuts"] == [[2]] and report["ids_within_shots"] == 0
    assert [(e["frame"], e["cut"]) for e in report["id_switch_events"][0]] == [(cut, 0), (cut, 0)]
    assert report["coverage"] == 1.0
    assert report["w_mpjpe"] > 100.0  # the switch costs pose error
    by_distance = evaluate(swapped, truth, body_model, id_association="root_distance")
    assert by_distance["ids"] == 2


def test_id_boxes_of_the_truth_are_its_projected_mesh_unless_given_is_asked(scene, body_model):
    # The dataset's boxes swap the two people for frames 10-14: "given" believes them, "mesh" (amodal
    # boxes of the true meshes, like the predicted ones) does not look at them.
    truth = scene()
    boxes = truth.bboxes.copy()
    boxes[[0, 1], 10:15] = boxes[[1, 0], 10:15]
    odd = replace(truth, bboxes=boxes)
    assert evaluate(truth.world, odd, body_model)["ids"] == 0
    given = evaluate(truth.world, odd, body_model, truth_boxes="given")
    assert given["ids"] == 4 and given["ids_within_shots"] == 4
    with pytest.raises(InputError, match="truth_boxes"):
        evaluate(truth.world, truth, body_model, truth_boxes="visible")


def test_one_new_identity_after_the_cut_and_misses(scene, body_model):
    truth = scene()
    cut = int(truth.world.cut_frames[0])
    split = _splice(truth.world, [[0, -1], [1, 1], [-1, 0]], cut)
    report = evaluate(split, truth, body_model)
    assert report["ids"] == 1
    # True person 0 is paired with one of its two predicted ids: the other half of its frames are misses,
    # not scored, so the pose errors stay zero.
    assert report["coverage"] == pytest.approx(0.75)
    assert report["mpjpe"] == pytest.approx(0.0, abs=1e-9) and report["w_mpjpe"] == pytest.approx(0.0, abs=1e-6)


def test_missed_frames_lower_coverage_and_are_not_scored(scene, body_model):
    truth = scene()
    valid = truth.world.valid.copy()
    valid[0, 5:10] = False
    transl = truth.world.transl.copy()
    transl[0, 5:10] += 50.0  # garbage where the person is missing
    report = evaluate(replace(truth.world, valid=valid, transl=transl), truth, body_model)
    assert report["coverage"] == pytest.approx(1 - 5 / 80)
    for key in ERROR_KEYS:
        assert report[key] == pytest.approx(0.0, abs=1e-6), key
    assert report["scored_frames"] == 75


def test_static_cameras_use_the_joint_fallback_for_ate(scene, body_model):
    truth = scene(moving=False)
    report = evaluate(_move_world(truth.world, np.random.default_rng(6)), truth, body_model)
    assert report["ate_fallback"] is True and report["ate_alignment"] == ["sim3_people_joints"]
    assert report["ate"] == pytest.approx(0.0, abs=1e-6)
    assert "degenerate" in report["notes"]["ate"]


def test_foot_sliding_of_standing_people(scene, body_model):
    truth = scene(walking=False)
    perfect = evaluate(truth.world, truth, body_model)
    # With truth, FS is the predicted displacement where the true foot moves < 1 cm: for a perfect
    # prediction it is the true residual foot motion (here from turning and swinging), below 10 mm.
    assert 0.0 < perfect["fs_gt"] < 10.0
    drift = np.arange(truth.world.num_frames)[None, :, None] * np.array([0.008, 0.0, 0.0])  # 8 mm/frame
    sliding = evaluate(replace(truth.world, transl=truth.world.transl + drift), truth, body_model)
    # The predicted feet as predicted: a drift of 8 mm per frame adds about 8 mm where the feet rest.
    assert sliding["fs_gt"] > perfect["fs_gt"] + 5.0
    assert sliding["fs"] > perfect["fs"] + 1.0
    # The reference: FS of the truth's own motion, which the truth scored against itself equals.
    assert perfect["fs"] == pytest.approx(perfect["fs_truth"], rel=1e-9)
    assert sliding["fs_truth"] == pytest.approx(perfect["fs_truth"], rel=1e-12)


def test_missing_keypoints_give_nan_pck_with_a_note(scene, body_model):
    truth = scene()
    report = evaluate(replace(truth.world, keypoints2d=None), truth, body_model)
    assert np.isnan(report["pck"]) and np.isnan(report["pck_005"])
    assert "keypoints2d" in report["notes"]["pck"]
    assert report["mpjpe"] == pytest.approx(0.0, abs=1e-9)


def test_gt_free_metrics_read_only_the_result(scene, body_model):
    truth, other = scene(seed=0), scene(seed=1)
    result = replace(truth.world, transl=truth.world.transl + np.array([0.0, 0.0, 0.02]))
    a, b = evaluate(result, truth, body_model), evaluate(result, other, body_model)
    for key in ("pck", "pck_005", "jitter", "fs"):
        assert a[key] == pytest.approx(b[key], rel=1e-12), key
    assert a["mpjpe_world"] != pytest.approx(b["mpjpe_world"])


def test_sequences_pool_frame_weighted_and_average_ids(scene, body_model):
    truth_a, truth_b = scene(seed=0), scene(seed=1, num_frames=60, cut=30)
    betas = truth_b.world.betas.copy()
    betas[0, 0] += 1.0  # a wrong shape for one person: non-zero MPJPE on its frames
    result_b = replace(truth_b.world, betas=betas)
    swapped_a = _splice(truth_a.world, [[0, 1], [1, 0]], int(truth_a.world.cut_frames[0]))
    single_b = evaluate(result_b, truth_b, body_model)
    pooled = evaluate_sequences([(swapped_a, truth_a), (result_b, truth_b)], body_model)
    single_a = evaluate(swapped_a, truth_a, body_model)
    frames_a, frames_b = 80, 120
    expected = (single_a["mpjpe"] * frames_a + single_b["mpjpe"] * frames_b) / (frames_a + frames_b)
    assert single_b["mpjpe"] > 1.0
    assert pooled["mpjpe"] == pytest.approx(expected, rel=1e-9)
    assert pooled["ids"] == pytest.approx(1.0) and pooled["ids_per_cut"] == pytest.approx(1.0)
    assert pooled["ids_total"] == 2 and pooled["ids_per_sequence"] == [2, 0]
    assert pooled["ids_at_cuts"] == [[2], [0]]
    assert pooled["num_sequences"] == 2 and pooled["coverage"] == 1.0


def _drifting_cameras(world: WorldResult, rng: np.random.Generator, amount: float) -> WorldResult:
    """The cameras' centres moved by a random walk (the people stay put)."""
    from multithumbs.geometry import camera_centre

    centres = camera_centre(world.R, world.t) + np.cumsum(rng.normal(0.0, amount, (world.num_frames, 3)), axis=0)
    return replace(world, t=-np.einsum("tij,tj->ti", world.R, centres))


def test_ate_over_two_sequences_is_the_mean_of_evo_per_sequence(scene, body_model):
    from tests.metrics.test_camera import _evo_ape
    from multithumbs.geometry import camera_centre

    rng = np.random.default_rng(7)
    pairs = []
    for seed, amount in ((0, 0.02), (1, 0.06)):
        truth = scene(seed=seed, num_frames=60, cut=30)
        pairs.append((_move_world(_drifting_cameras(truth.world, rng, amount), rng), truth))
    pooled = evaluate_sequences(pairs, body_model)
    evo = [_evo_ape(camera_centre(r.R, r.t), camera_centre(g.world.R, g.world.t)) for r, g in pairs]
    np.testing.assert_allclose(pooled["ate_per_sequence"], [rmse for rmse, _ in evo], rtol=1e-6)
    assert pooled["ate"] == pytest.approx(np.mean([rmse for rmse, _ in evo]), rel=1e-6)
    assert pooled["ate_mean"] == pytest.approx(np.mean([mean for _, mean in evo]), rel=1e-6)
    assert pooled["ate_alignment"] == ["sim3_camera_centres"] * 2
    # Not the pooled RMSE over all frames, which weighs the worse sequence's errors quadratically.
    errors = [evaluate(r, g, body_model)["ate"] for r, g in pairs]
    pooled_rmse = np.sqrt(np.mean(np.square(errors)))
    assert abs(pooled["ate"] - pooled_rmse) > 1e-3


def test_empty_prediction_scores_nothing_without_crashing(scene, body_model):
    truth = scene()
    report = evaluate(_splice(truth.world, [], int(truth.world.cut_frames[0])), truth, body_model)
    assert report["coverage"] == 0.0 and report["ids"] == 0
    for key in ("mpjpe", "w_mpjpe", "jitter", "fs", "pck"):
        assert np.isnan(report[key]) and key in report["notes"], key


def test_bad_inputs_raise_input_errors(scene, body_model):
    truth = scene()
    with pytest.raises(InputError, match="unknown"):
        evaluate(truth.world, truth, body_model, chunks=100)
    with pytest.raises(InputError, match="id_association"):
        evaluate(truth.world, truth, body_model, id_association="appearance")
    shorter = scene(num_frames=30, cut=15)
    with pytest.raises(InputError, match="frames"):
        evaluate(shorter.world, truth, body_model)
    with pytest.raises(InputError, match="nothing"):
        evaluate_sequences([], body_model)
