
import numpy as np
import pytest

from multithumbs.appearance import appearance_dissimilarity, describe_person, mean_descriptor
from multithumbs.errors import InputError
from multithumbs.perception.appearance import complete_skeleton, fill_appearance, uv_outliers
from multithumbs.perception.phalp import load_phalp
from multithumbs.synth.perception import true_track_people


def test_complete_skeleton_fills_torso_and_head_only_where_missing():
    kp = np.zeros((2, 24, 3))
    kp[:, 1], kp[:, 2] = [10, 100, 1], [30, 100, 1]      # hips
    kp[:, 16], kp[:, 17] = [5, 40, 0.8], [35, 40, 0.9]    # shoulders
    kp[1, 15] = [99, 99, 1.0]                             # a real head joint is kept
    out = complete_skeleton(kp)
    np.testing.assert_allclose(out[0, 0], [20, 100, 1])
    np.testing.assert_allclose(out[0, 12], [20, 40, 0.8])
    np.testing.assert_allclose(out[0, 6], [20, 70, 0.8])
    np.testing.assert_allclose(out[0, 15], [20, 100 - 1.4 * 60, 0.8])
    np.testing.assert_allclose(out[1, 15], [99, 99, 1.0])
    assert np.all(out[:, [4, 5, 7, 8, 18, 19, 20, 21], 2] == 0)   # limbs are never invented
    np.testing.assert_array_equal(kp[0, 0], 0)                    # input untouched


def test_uv_outliers():
    rng = np.random.default_rng(0)
    codes = rng.normal(0, 0.01, (2, 10, 8)) + np.arange(8)
    codes[0, 4] += 5.0
    valid = np.ones((2, 10), bool)
    valid[1, 3:] = False
    out = uv_outliers(codes, valid)
    assert out[0].tolist() == [j == 4 for j in range(10)]
    assert not out[1].any()                                         # too few codes to vet


@pytest.fixture(scope="module")
def imported(scene, results_file):
    video, shots = scene
    return load_phalp(results_file, shots, video.truth.world.image_size, trust=True)


def test_fill_appearance_from_pixels(imported, scene, video_file):
    video, _ = scene
    filled = fill_appearance(imported.tracks, video.frames)
    for tr in filled:
        assert tr.appearance.shape[:2] == tr.valid.shape
        assert tr.appearance_valid.sum() >= 0.9 * tr.valid.sum()
        assert not tr.appearance_valid[~tr.valid].any()
        i, j = np.argwhere(tr.appearance_valid)[0]
        expected = describe_person(video.frames[tr.start_frame + j], tr.mask(i, j),
                                   complete_skeleton(tr.keypoints2d[i, j]))
        np.testing.assert_allclose(tr.appearance[i, j], expected)
    # From the decoded MPEG-4 file (lossy at this size): each descriptor is closer to the same person's from
    # the rendered pixels than to the other person's.
    decoded = fill_appearance(imported.tracks, video_file)
    for a, b in zip(filled, decoded):
        both = a.appearance_valid & b.appearance_valid
        same = appearance_dissimilarity(a.appearance[both], b.appearance[both]).mean()
        other = appearance_dissimilarity(a.appearance[::-1][both[::-1] & both], b.appearance[both[::-1] & both]).mean()
        assert same < other


def test_pixel_appearance_tells_people_apart(imported, scene):
    # Accuracy on the synthetic scene: each person's descriptor is closer to their own in the other shot.
    video, _ = scene
    filled = fill_appearance(imported.tracks, video.frames)
    people = [true_track_people(tr, video) for tr in filled]
    mean = [{int(p): mean_descriptor(tr.appearance[i], tr.appearance_valid[i]) for i, p in enumerate(ids)}
            for tr, ids in zip(filled, people)]
    common = sorted(set(mean[0]) & set(mean[1]))
    assert len(common) == 2
    cost = np.array([[appearance_dissimilarity(mean[0][a], mean[1][b]) for b in common] for a in common])
    assert np.all(np.diag(cost) < cost.min(axis=1, where=~np.eye(2, dtype=bool), initial=1.0))


def test_uv_codes_vet_descriptors(imported, scene):
    video, _ = scene
    tr = imported.tracks[0]
    codes = np.tile(np.arange(8.0), (*tr.valid.shape, 1)) + np.random.default_rng(0).normal(0, 0.01, (*tr.valid.shape, 8))
    i, j = np.argwhere(tr.valid)[2]
    codes[i, j] += 3.0
    plain = fill_appearance([tr], video.frames)[0]
    vetted = fill_appearance([tr], video.frames, [codes], [tr.valid])[0]
    assert plain.appearance_valid[i, j] and not vetted.appearance_valid[i, j]
    np.testing.assert_array_equal(vetted.appearance, plain.appearance)
    assert (plain.appearance_valid & ~vetted.appearance_valid).sum() == 1


def test_bad_frames(imported, scene):
    video, _ = scene
    with pytest.raises(InputError, match="the video ends at frame 10"):
        fill_appearance(imported.tracks, video.frames[:10])
    with pytest.raises(InputError, match="is 48x80, the tracks are for 96x160"):
        fill_appearance(imported.tracks, video.frames[:, ::2, ::2])
