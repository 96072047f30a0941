import numpy as np
from scipy.spatial.transform import Rotation

from multithumbs.geometry import camera_centre
from multithumbs.method.align import point_maps_with_sources
from multithumbs.method.views import register_views, smoothed_depth
from multithumbs.synth.simulated_geometry import SharedSpaceNoise, simulate_shared_space


def _metric_inputs(space, scale):
    """Point maps in each camera's frame and the cameras, brought to metric units."""
    maps, valid, single, own = point_maps_with_sources(space)
    maps = maps / scale
    t = space.t / scale
    point_cam = np.einsum("kij,khwj->khwi", space.R, maps) + t[:, None, None]
    return point_cam, valid & single, space.R, t, own


def _relative_error(R, t, R_ref, t_ref):
    """Rotation (deg) and centre (m) error of frame 1 relative to frame 0, against a reference pair."""
    rot = Rotation.from_matrix(R[1] @ R[0].T @ (R_ref[1] @ R_ref[0].T).T).magnitude()
    c, c_ref = camera_centre(R, t), camera_centre(R_ref, t_ref)
    return np.rad2deg(rot), np.linalg.norm(R[0] @ (c[1] - c[0]) - R_ref[0] @ (c_ref[1] - c_ref[0]))


def test_registration_recovers_a_known_camera_error(tiny):
    scale = float(tiny.space_from_world[0].numpy()[0])
    clean = tiny.spaces[0]
    _, _, R_ref, t_ref, _ = _metric_inputs(clean, scale)
    # Camera errors carry each frame's points with them (same random frame as the clean space).
    noisy = simulate_shared_space(tiny.video, 0, SharedSpaceNoise(depth_sigma=0.0, rotation_deg=2.0,
                                                                  translation_sigma=0.03))
    point_cam, usable, R, t, own = _metric_inputs(noisy, scale)
    rot0, centre0 = _relative_error(R, t, R_ref, t_ref)
    assert rot0 > 1.0 and centre0 > 0.03  # a real error to undo
    out = register_views(point_cam, usable, noisy.K, R, t, observed=own)
    rot1, centre1 = _relative_error(out.R, out.t, R_ref, t_ref)
    assert out.registered and rot1 < 0.2 and centre1 < 0.03, (rot0, rot1, centre0, centre1)
    np.testing.assert_array_equal(out.R[0], R[0])  # the first frame fixes the gauge
    assert out.residual_after < out.residual_before


def test_consistent_frames_stay_where_they_are(tiny):
    scale = float(tiny.space_from_world[0].numpy()[0])
    point_cam, usable, R, t, own = _metric_inputs(tiny.spaces[0], scale)
    out = register_views(point_cam, usable, tiny.spaces[0].K, R, t, observed=own)
    rot, centre = _relative_error(out.R, out.t, R, t)
    assert out.registered and rot < 0.05 and centre < 0.01


def test_too_few_points_leave_the_cameras_alone(tiny):
    scale = float(tiny.space_from_world[0].numpy()[0])
    point_cam, usable, R, t, own = _metric_inputs(tiny.spaces[0], scale)
    out = register_views(point_cam, np.zeros_like(usable), tiny.spaces[0].K, R, t)
    assert not out.registered and out.points_used == 0
    np.testing.assert_array_equal(out.R, R)
    np.testing.assert_array_equal(out.t, t)


def test_smoothed_depth_keeps_a_plane_and_ignores_invalid_pixels():
    v, u = np.mgrid[0:40, 0:60]
    plane = 1.0 / (0.3 + 0.002 * u + 0.004 * v)   # a plane's depth: its inverse is linear in the pixels
    valid = np.ones_like(plane, bool)
    valid[:, 30:] = False
    garbage = np.where(valid, plane, 100.0)
    out = smoothed_depth(garbage, valid, 2.0)
    inner = np.zeros_like(valid)
    inner[9:-9, 9:21] = True   # farther from the support's borders than the kernel reaches (4 sigma)
    np.testing.assert_allclose(out[inner], plane[inner], atol=1e-9)
    assert np.all(out[~valid] == 0)


def test_a_rounding_level_change_of_the_points_moves_the_result_by_rounding_only(tiny):
    # A 1e-12 relative change of every point must not switch points in or out between the solver's
    # steps and send it down another path. The hard gates pass here; on the standard suite they do not
    # everywhere (s06 cut 0 moves 0.2 deg: benchmarks/view_registration.py --perturb 1e-12, issue 18).
    scale = float(tiny.space_from_world[0].numpy()[0])
    noisy = simulate_shared_space(tiny.video, 0, SharedSpaceNoise(depth_sigma=0.01, rotation_deg=2.0,
                                                                  translation_sigma=0.03))
    point_cam, usable, R, t, own = _metric_inputs(noisy, scale)
    out = register_views(point_cam, usable, noisy.K, R, t, observed=own)
    nudge = 1.0 + 1e-12 * np.random.default_rng(0).standard_normal(point_cam.shape)
    nudged = register_views(point_cam * nudge, usable, noisy.K, R, t, observed=own)
    rot, centre = _relative_error(nudged.R, nudged.t, out.R, out.t)
    assert out.registered and nudged.registered
    assert rot < 1e-6 and centre < 1e-6, (rot, centre)
