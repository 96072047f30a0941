import numpy as np

from multithumbs.scene.two_view_dense import interpolate_room


def test_room_interpolation_is_exact_on_a_plane():
    rng = np.random.default_rng(1)
    xy = rng.uniform([0, 0], [99, 59], (60, 2))
    inverse = 0.2 + 0.001 * xy[:, 0] + 0.002 * xy[:, 1]  # a plane: inverse depth affine in the image
    pix, depth = interpolate_room(xy, 1 / inverse, np.zeros((60, 100), bool), (60, 100), 2, 1e9)
    assert len(pix) > 500
    np.testing.assert_allclose(1 / depth, 0.2 + 0.001 * pix[:, 0] + 0.002 * pix[:, 1], rtol=1e-9)
