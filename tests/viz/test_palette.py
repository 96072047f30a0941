import numpy as np

from multithumbs.viz.palette import id_color, id_color_u8, id_colors


def test_colours_are_stable_and_distinct():
    ids = np.arange(30)
    colours = id_colors(ids)
    assert colours.shape == (30, 3) and colours.min() >= 0 and colours.max() <= 1
    np.testing.assert_array_equal(id_colors(ids[::-1]), colours[::-1])  # a function of the id alone
    gaps = np.linalg.norm(colours[:, None] - colours[None], axis=-1) + np.eye(30)
    assert gaps[:10, :10].min() > 0.15
    assert len({tuple(np.round(c, 3)) for c in colours}) == 30
    assert id_color_u8(0) == (31, 119, 180)
    assert id_colors([]).shape == (0, 3)
    assert np.all(np.isfinite(id_color(-3)))
