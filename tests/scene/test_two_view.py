import numpy as np
import pytest

from multithumbs.errors import InputError
from multithumbs.scene.two_view import (
    default_intrinsics,
    estimate_two_view,
    shared_space_at_cut,
)
from multithumbs.scene.two_view_pose import TwoViewConfig
from multithumbs.types import SharedSpace
from tests.scene.conftest import direction_error_deg, relative, rotation_error_deg


def _cut(clip):
    cut = int(clip.world.cut_frames[0])
    return cut, cut - 1, cut


def test_relative_pose_and_points_match_the_truth(static_clip):
    cut, a, b = _cut(static_clip)
    w, video = static_clip.world, static_clip.video
    result = estimate_two_view(video.frames[a], video.frames[b], w.K[a], static_clip.person_masks(a),
                               static_clip.person_masks(b), cut)
    space = result.space
    assert isinstance(space, SharedSpace) and space.source == "pycolmap" and space.fallback == ""
    assert space.cut_frame == cut and space.image_size == w.image_size
    assert result.num_inliers >= 30 and 0 < result.num_triangulated <= result.num_inliers <= result.num_matches
    R_true, t_true = relative(w.R[[a, b]], w.t[[a, b]])
    R_est, t_est = relative(space.R, space.t)
    assert rotation_error_deg(R_est, R_true) < 1.0
    assert direction_error_deg(t_est, t_true) < 3.0
    np.testing.assert_allclose(space.R[0], np.eye(3), atol=1e-12)
    assert np.linalg.norm(t_est) == pytest.approx(1.0)
    # Depths agree with the renderer's up to the space's one scale; people's points lie on people.
    h, w_ = space.image_size
    for k, f in ((0, a), (1, b)):
        sel = space.observed[k]
        pix = space.pixels[k, sel]
        assert (pix >= -0.5).all() and (pix[:, 0] <= w_ - 0.5).all() and (pix[:, 1] <= h - 0.5).all()
        u, v = np.round(pix).astype(int).T
        depth = (space.points[sel] @ space.R[k].T + space.t[k])[:, 2]
        true = video.boundary_depth[0, k][v, u]
        on_person = video.instance[f][v, u] >= 0
        ok = np.isfinite(true)
        scale = np.median(true[ok & ~on_person] / depth[ok & ~on_person])
        rel = np.abs(depth * scale - true) / true
        assert np.median(rel[ok & ~on_person]) < 0.01
        assert on_person.sum() > 200 and np.median(rel[ok & on_person]) < 0.05
    both = space.observed.all(axis=0)
    assert both.sum() == result.num_triangulated
    assert ((space.confidence >= 0) & (space.confidence <= 1)).all()


def test_black_uniform_and_textureless_frames_fall_back(static_clip):
    cut, a, b = _cut(static_clip)
    frames, K = static_clip.video.frames, static_clip.world.K[a]
    black = np.zeros_like(frames[a])
    grey = np.full_like(frames[a], 128)
    for frame_a, frame_b in ((frames[a], black), (grey, frames[b]), (black, black)):
        space = shared_space_at_cut(frame_a, frame_b, K, None, None, cut)
        assert space.fallback == "human_only" and len(space.points) == 0
        np.testing.assert_allclose(space.R, np.tile(np.eye(3), (2, 1, 1)))


def test_people_join_the_pose_when_the_room_is_hidden(static_clip):
    cut, a, b = _cut(static_clip)
    video = static_clip.video
    everything = np.ones(video.frames.shape[1:3], bool)
    space = shared_space_at_cut(video.frames[a], video.frames[b], static_clip.world.K[a], everything, everything, cut)
    assert space.fallback == "with_people"


def test_neighbour_frames_fallback(static_clip):
    cut, a, b = _cut(static_clip)
    video, K = static_clip.video, static_clip.world.K[a]
    hidden = np.ones(video.frames.shape[1:3], bool)
    hidden[:, :20] = False  # the boundary frames show only a sliver of room
    config = TwoViewConfig(min_inliers=60)
    space = shared_space_at_cut(video.frames[a], video.frames[b], K, hidden, hidden, cut, config,
                                [video.frames[a - 1]], [video.frames[b + 1]], [None], [None])
    assert space.fallback == "neighbour_frames"


def test_bad_inputs(static_clip):
    frame = static_clip.video.frames[0]
    K = static_clip.world.K[0]
    with pytest.raises(InputError, match="frame_b"):
        shared_space_at_cut(frame, frame[:50], K)
    with pytest.raises(InputError, match="uint8"):
        shared_space_at_cut(frame.astype(float), frame, K)
    with pytest.raises(InputError, match="K"):
        shared_space_at_cut(frame, frame, np.eye(4))
    with pytest.raises(InputError, match="masks_a"):
        shared_space_at_cut(frame, frame, K, np.zeros((5, 5), bool))


def test_default_intrinsics():
    K = default_intrinsics(640, 360)
    assert K[0, 0] == pytest.approx(320 / np.tan(np.radians(30)))
    assert (K[0, 2], K[1, 2]) == (319.5, 179.5) and K[0, 0] == K[1, 1]
    with pytest.raises(InputError):
        default_intrinsics(0, 10)
