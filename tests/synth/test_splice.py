import numpy as np
import pytest

from multithumbs.errors import InputError
from multithumbs.synth.splice import even_cuts, shot_camera_ids, splice_views


def test_even_cuts_are_balanced_and_respect_min_length():
    np.testing.assert_array_equal(even_cuts(120, 2), [60])
    np.testing.assert_array_equal(even_cuts(90, 3), [30, 60])
    cuts = even_cuts(20, 4, jitter=0.5, rng=np.random.default_rng(0), min_shot_length=4)
    edges = np.concatenate([[0], cuts, [20]])
    assert np.all(np.diff(edges) >= 4)
    with pytest.raises(InputError, match="frames"):
        even_cuts(3, 2)


def test_splice_takes_each_shot_from_its_camera():
    ids = shot_camera_ids(6, [2, 4], [2, 0, 1])
    np.testing.assert_array_equal(ids, [2, 2, 0, 0, 1, 1])
    per_view = np.arange(3)[:, None, None] * 100 + np.arange(6)[None, :, None]  # (V, T, 1): view*100 + t
    np.testing.assert_array_equal(splice_views(per_view, ids)[:, 0], [200, 201, 2, 3, 104, 105])
    with pytest.raises(InputError, match="camera_order"):
        shot_camera_ids(6, [2, 4], [0, 1])
