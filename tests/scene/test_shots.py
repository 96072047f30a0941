import numpy as np
import pytest

from multithumbs.errors import InputError
from multithumbs.scene.shots import ShotConfig, boundary_frames, detect_shots
from multithumbs.synth.files import write_video
from multithumbs.types import Shots


def test_detects_true_cut_from_frames_and_file(static_clip, tmp_path):
    frames, truth = static_clip.video.frames, static_clip.world.cut_frames
    shots = detect_shots(frames, fps=30.0)
    assert shots.cut_frames.tolist() == truth.tolist()
    assert shots.scores.shape == (len(frames),) and shots.scores[0] == 0
    assert shots.source == "scenedetect:adaptive"
    # The cut has by far the largest change score.
    assert int(np.argmax(shots.scores)) == int(truth[0])
    path = write_video(tmp_path / "clip.mp4", frames, 30.0)
    for detector in ("adaptive", "content", "histogram"):
        from_file = detect_shots(path, ShotConfig(detector=detector))
        assert from_file.cut_frames.tolist() == truth.tolist(), detector
        assert from_file.num_frames == len(frames) and from_file.fps == pytest.approx(30.0)


def test_thresholds_and_min_length_are_honoured(static_clip):
    frames = static_clip.video.frames
    assert detect_shots(frames, ShotConfig(detector="content", content_threshold=250.0)).cut_frames.size == 0
    cut = int(static_clip.world.cut_frames[0])
    assert detect_shots(frames, ShotConfig(min_shot_length=cut + 1)).cut_frames.size == 0


def test_no_false_cut_in_a_continuous_moving_shot(moving_clip):
    frames = moving_clip.video.frames
    cut = int(moving_clip.world.cut_frames[0])
    assert detect_shots(frames[:cut]).cut_frames.size == 0
    assert detect_shots(frames[cut:]).cut_frames.size == 0


def test_bad_inputs(tmp_path):
    with pytest.raises(InputError, match="no such video"):
        detect_shots(tmp_path / "missing.mp4")
    (tmp_path / "junk.mp4").write_bytes(b"not a video")
    with pytest.raises(InputError):
        detect_shots(tmp_path / "junk.mp4")
    with pytest.raises(InputError, match="uint8"):
        detect_shots(np.zeros((4, 8, 8, 3), np.float32))
    with pytest.raises(InputError, match="no frames"):
        detect_shots(np.zeros((0, 8, 8, 3), np.uint8))
    with pytest.raises(InputError, match="detector"):
        ShotConfig(detector="magic")


def test_all_fades_video_gives_a_clear_outcome():
    """Two flat-colour 'shots' joined by slow fades: no crash, no cut inside a fade's mixed frames."""
    rng = np.random.default_rng(0)
    a = rng.integers(0, 255, (24, 32, 3)).astype(np.float64)
    b = rng.integers(0, 255, (24, 32, 3)).astype(np.float64)
    ramp = np.r_[np.ones(20), np.linspace(1, 0, 20), np.zeros(20)]
    frames = np.stack([w * a + (1 - w) * b for w in ramp]).round().astype(np.uint8)
    shots = detect_shots(frames)
    assert shots.num_frames == 60
    for c in range(shots.cut_frames.size):  # a cut found in the fade gives boundary frames off the fade
        pair = boundary_frames(shots, c, max_offset=30)
        assert pair.before < 21 or pair.after > 39 or pair.shifted


def test_boundary_frames_of_a_clean_cut_and_of_transitions():
    scores = np.full(40, 1.0)
    scores[0] = 0
    scores[20] = 50.0
    shots = Shots(np.array([20]), 30.0, 40, scores, "test")
    pair = boundary_frames(shots, 0)
    assert (pair.before, pair.after) == (19, 20) and not pair.shifted
    # The detector is one frame early: the real change is into frame 21, so frame 20 is still the old shot.
    late = scores.copy()
    late[20], late[21] = 1.0, 50.0
    pair = boundary_frames(Shots(np.array([20]), 30.0, 40, late, "test"), 0)
    assert pair.after == 21 and pair.before == 19
    # A fade over frames 18-22: both frames step off it.
    fade = scores.copy()
    fade[18:23] = 12.0
    pair = boundary_frames(Shots(np.array([20]), 30.0, 40, fade, "test"), 0)
    assert pair.before == 17 and pair.after == 22
    # Ground-truth shots (zero scores) keep the conventions' pair.
    zero = Shots(np.array([20]), 30.0, 40, np.zeros(40), "ground_truth")
    assert (boundary_frames(zero, 0).before, boundary_frames(zero, 0).after) == (19, 20)
    with pytest.raises(InputError, match="cut_index"):
        boundary_frames(zero, 1)


def test_single_frame_shot_keeps_boundary_frames_inside_their_shots():
    scores = np.ones(30)
    scores[[10, 11]] = 60.0
    shots = Shots(np.array([10, 11]), 30.0, 30, scores, "test")
    for c in range(2):
        pair = boundary_frames(shots, c)
        (a0, a1), (b0, b1) = shots.ranges[c], shots.ranges[c + 1]
        assert a0 <= pair.before < a1 and b0 <= pair.after < b1
