"""End to end: shots, trajectories and shared spaces computed from pixels feed the method's reference chain."""

import numpy as np

from multithumbs.method.align import AlignConfig
from multithumbs.method.post import PostConfig
from multithumbs.pipeline import MethodConfig, run_video
from multithumbs.scene import detect_shots, scene_geometry
from multithumbs.synth.perception import simulate_perception


def test_pixels_to_run_video(static_clip, body):
    video = static_clip.video
    world = video.truth.world
    shots = detect_shots(video.frames, fps=world.fps)
    assert shots.cut_frames.tolist() == world.cut_frames.tolist()
    tracks = simulate_perception(video, body)
    masks = video.instance >= 0
    geometry = scene_geometry(video.frames, shots, world.K[0], masks)
    assert len(geometry.trajectories) == shots.num_shots and len(geometry.spaces) == shots.cut_frames.size
    assert all(s.source == "pycolmap" for s in geometry.spaces)
    assert [t.source for t in geometry.trajectories] == ["static", "static"]
    fast = MethodConfig(align=AlignConfig(iterations=(0, 40, 80)), post=PostConfig(iterations=20))
    result = run_video(shots, tracks, geometry.trajectories, geometry.spaces, body, fast)
    assert result.num_frames == world.num_frames
    assert np.isfinite(result.transl[result.valid]).all() and np.isfinite(result.R).all()
    # The shared space's people gave the scale: it is finite and positive.
    assert np.isfinite(result.diagnostics["space_scale_cut0"]) and result.diagnostics["space_scale_cut0"] > 0


def test_moving_clip_geometry(moving_clip):
    video = moving_clip.video
    world = video.truth.world
    geometry = scene_geometry(video.frames, world.shots(), world.K, video.instance >= 0)
    assert [t.source for t in geometry.trajectories] == ["pycolmap", "pycolmap"]
    assert geometry.boundary == ((int(world.cut_frames[0]) - 1, int(world.cut_frames[0])),)
    assert set(geometry.seconds) == {"trajectories", "spaces"}
