import numpy as np

from multithumbs.method.align import AlignConfig, align_boundary, point_maps
from multithumbs.pipeline import boundary_people
from multithumbs.synth.perception import true_track_people

from .conftest import apply, metric_frame

FAST = AlignConfig(iterations=(0, 100, 200))


def _true_pelvis(tiny, body, side, cut=0):
    world = tiny.video.truth.world
    frame = int(world.cut_frames[cut]) - 1 + side
    pelvis_rest = body.rest_joints(world.betas).double().numpy()[:, 0]
    return world.transl[:, frame] + pelvis_rest


def test_point_maps_cover_the_image_and_keep_exact_points(tiny):
    maps, valid = point_maps(tiny.spaces[0])
    assert valid.mean() > 0.99  # strided maps are filled to full resolution
    sel = tiny.spaces[0].observed[0]
    uv = np.round(tiny.spaces[0].pixels[0, sel]).astype(int)
    np.testing.assert_allclose(maps[0][uv[:, 1], uv[:, 0]], tiny.spaces[0].points[sel])


def test_alignment_recovers_a_known_offset_and_scale(tiny, body):
    people = boundary_people(tiny.tracks[0], tiny.tracks[1], body)
    space_from_world = tiny.space_from_world[0]
    # The space was built at an unknown scale s and in an arbitrary frame: the method must undo the scale ...
    s = float(space_from_world.numpy()[0])
    for config in (FAST, AlignConfig(iterations=(0, 100, 200), refine_cameras=False)):
        aligned = align_boundary(people, tiny.spaces[0], config)
        assert abs(aligned.scale * s - 1) < 0.01
        # ... and place every person where the truth lands in the space's (metric) frame.
        rigid = metric_frame(space_from_world)
        for side in (0, 1):
            truth_idx = true_track_people([tiny.tracks[0], tiny.tracks[1]][side], tiny.video)
            expected = apply(rigid, _true_pelvis(tiny, body, side))
            for j in np.nonzero(aligned.present[side])[0]:
                p = truth_idx[aligned.track_index[side, j]]
                assert np.linalg.norm(aligned.pelvis[side, j] - expected[p]) < 0.03
        assert np.all(np.diff(aligned.losses[-50:]) < 1e-3)  # settled


def test_a_cut_with_nobody_on_one_side_is_a_documented_outcome(tiny, body):
    import dataclasses
    empty = dataclasses.replace(tiny.tracks[1], valid=np.zeros_like(tiny.tracks[1].valid))
    people = boundary_people(tiny.tracks[0], empty, body)
    aligned = align_boundary(people, tiny.spaces[0], AlignConfig(iterations=(0, 20, 20)))
    assert not aligned.present[1].any() and aligned.present[0].any()
    assert np.isfinite(aligned.pelvis[0][aligned.present[0]]).all() and np.isfinite(aligned.scale)


def _depth_corrupted(people, factors):
    """The boundary people with each estimated pelvis moved along its pixel ray by a per-person factor."""
    import dataclasses
    pelvis = people.pelvis_cam * np.asarray(factors)[None, :, None]
    return dataclasses.replace(people, pelvis_cam=pelvis)


def test_keypoint_fit_recovers_depth_lost_along_the_ray(tiny, body):
    from multithumbs.method.align import fit_pelvis_to_keypoints
    people = boundary_people(tiny.tracks[0], tiny.tracks[1], body)
    K = tiny.spaces[0].K[0]
    truth = people.pelvis_cam[0, 0]
    for factor in (0.8, 1.25):  # a monocular estimator's depth error keeps the pixel, not the size
        fitted = fit_pelvis_to_keypoints(people.local_joints[0, 0], people.orient_cam[0, 0], truth * factor,
                                         people.keypoints[0, 0], K)
        np.testing.assert_allclose(fitted, truth, rtol=2e-3)
    # Too few confident keypoints: the estimator's placement is kept.
    blind = people.keypoints[0, 0].copy()
    blind[:, 2] = 0.0
    np.testing.assert_array_equal(fit_pelvis_to_keypoints(people.local_joints[0, 0], people.orient_cam[0, 0],
                                                          truth * 1.1, blind, K), truth * 1.1)


def test_space_scale_does_not_inherit_the_estimators_depth_error(tiny, body):
    from multithumbs.method.align import estimate_space_scale, keypoint_fitted_pelvis
    people = _depth_corrupted(boundary_people(tiny.tracks[0], tiny.tracks[1], body), [1.15, 1.1])
    space = tiny.spaces[0]
    s = float(tiny.space_from_world[0].numpy()[0])
    maps, valid = point_maps(space)
    raw = estimate_space_scale(people, space, maps, valid, 20)
    fitted = estimate_space_scale(people, space, maps, valid, 20, pelvis_cam=keypoint_fitted_pelvis(people, space.K, 0.3))
    assert abs(raw * s - 1) > 0.08  # the estimator's depth error passes into the scale ...
    assert abs(fitted * s - 1) < 0.01  # ... the meshes' size does not carry it


def test_torch_threads_are_restored():
    import pytest
    import torch

    from multithumbs.method.align import torch_threads
    before = torch.get_num_threads()
    with torch_threads(1):
        assert torch.get_num_threads() == 1
    assert torch.get_num_threads() == before
    with pytest.raises(RuntimeError), torch_threads(1):
        raise RuntimeError("boom")
    assert torch.get_num_threads() == before
