import cv2
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


# --- One-frame outliers (glitches, flashes) -----------------------------------------------------------

def white_block(frame: np.ndarray) -> np.ndarray:
    """A glitch on a sixteenth of the frame: the rest of the frame is intact."""
    out = frame.copy()
    h, w = frame.shape[:2]
    out[h // 4:h // 2, w // 4:w // 2] = 255
    return out


def magenta_flash(frame: np.ndarray) -> np.ndarray:
    """A full-frame flash of one colour: nothing of the frame is left."""
    return np.broadcast_to(np.array([255, 0, 255], np.uint8), frame.shape).copy()


def corrupted(frames: np.ndarray, at: int, glitch) -> np.ndarray:
    out = frames.copy()
    out[at] = glitch(out[at])
    return out


def pairs_of(shots: Shots) -> list[tuple[int, int]]:
    return [(p.before, p.after) for p in (boundary_frames(shots, c) for c in range(shots.cut_frames.size))]


@pytest.mark.parametrize("glitch", [white_block, magenta_flash], ids=["white_block", "flash"])
@pytest.mark.parametrize("clip_name", ["static_clip", "moving_clip"])
def test_glitch_in_mid_shot_is_not_a_cut(request, clip_name, glitch):
    """A corrupted frame inside either shot: no false cut (the old detectors cut at a flash, the histogram
    detector at a white block), the true cut and its boundary pair unchanged, the frame reported."""
    clip = request.getfixturevalue(clip_name)
    frames, cut = clip.video.frames, int(clip.world.cut_frames[0])
    for detector in ("adaptive", "content", "histogram"):
        config = ShotConfig(detector=detector)
        for at in (8, len(frames) - 9):
            shots = detect_shots(corrupted(frames, at, glitch), config)
            assert shots.cut_frames.tolist() == [cut], (detector, at)
            assert pairs_of(shots) == [(cut - 1, cut)], (detector, at)
            assert shots.outlier_frames.tolist() == [at], (detector, at)


@pytest.mark.parametrize("offset", [-1, 0, 1], ids=["last_of_shot", "first_of_shot", "second_of_shot"])
@pytest.mark.parametrize("clip_name", ["static_clip", "moving_clip"])
def test_glitch_next_to_a_cut_does_not_move_it(request, clip_name, offset):
    """A white block at t_b - 1, t_b or t_b + 1: the cut stays at t_b and neither boundary frame is the
    corrupted one (the old histogram detector moved the cut to the glitch at t_b - 1 and paired it at t_b)."""
    clip = request.getfixturevalue(clip_name)
    frames, cut = clip.video.frames, int(clip.world.cut_frames[0])
    at = cut + offset
    for detector in ("adaptive", "content", "histogram"):
        shots = detect_shots(corrupted(frames, at, white_block), ShotConfig(detector=detector))
        assert shots.cut_frames.tolist() == [cut], detector
        (before, after), = pairs_of(shots)
        assert at not in (before, after), detector
        assert cut - 3 <= before < cut <= after <= cut + 3, detector
        assert shots.outlier_frames.tolist() == [at], detector


@pytest.mark.parametrize("clip_name", ["static_clip", "moving_clip"])
def test_flash_next_to_a_cut(request, clip_name):
    """A full-frame flash keeps nothing that tells which shot it replaced: it is counted with the earlier
    shot. On the last frame of a shot (and on the second of the next) the cut stays at t_b (the old
    adaptive detector moved it to the flash, or lost it); on the first frame of a shot it moves to
    t_b + 1. Either way the boundary pair is the clean frames around the flash."""
    clip = request.getfixturevalue(clip_name)
    frames, cut = clip.video.frames, int(clip.world.cut_frames[0])
    expected = {cut - 1: (cut, (cut - 2, cut)), cut: (cut + 1, (cut - 1, cut + 1)), cut + 1: (cut, (cut - 1, cut))}
    for at, (cut_found, pair) in expected.items():
        shots = detect_shots(corrupted(frames, at, magenta_flash))
        assert shots.cut_frames.tolist() == [cut_found], at
        assert pairs_of(shots) == [pair], at
        assert shots.outlier_frames.tolist() == [at], at


def test_flash_in_a_video_file(static_clip, tmp_path):
    """The same from an encoded file: the codec's smearing does not turn the flash into a cut."""
    frames, cut = static_clip.video.frames, int(static_clip.world.cut_frames[0])
    path = write_video(tmp_path / "flash.mp4", corrupted(frames, 8, magenta_flash), 30.0)
    shots = detect_shots(path)
    assert shots.cut_frames.tolist() == [cut] and shots.outlier_frames.tolist() == [8]


def test_clean_cuts_and_short_shots_are_not_outliers(static_clip, moving_clip):
    """No outlier in clean videos: the frames either side of a hard cut each agree with their own shot.
    A shot of two frames is kept; a genuine one-frame shot is an outlier and is dropped (documented)."""
    for clip in (static_clip, moving_clip):
        for detector in ("adaptive", "content", "histogram"):
            shots = detect_shots(clip.video.frames, ShotConfig(detector=detector))
            assert shots.cut_frames.tolist() == clip.world.cut_frames.tolist(), detector
            assert shots.outlier_frames.size == 0, detector
    a = static_clip.video.frames
    b = np.stack([cv2.resize(f, a.shape[2:0:-1], interpolation=cv2.INTER_AREA) for f in moving_clip.video.frames])
    config = ShotConfig(min_shot_length=1)
    two = np.concatenate([a[:10], b[30:32], a[25:35]])  # three different views, the middle one two frames long
    shots = detect_shots(two, config)
    assert shots.cut_frames.tolist() == [10, 12] and shots.outlier_frames.size == 0
    one = np.concatenate([a[:10], b[30:31], a[25:35]])
    shots = detect_shots(one, config)
    assert shots.cut_frames.tolist() == [11] and shots.outlier_frames.tolist() == [10]
    as_is = detect_shots(one, ShotConfig(min_shot_length=1, reject_flash_frames=False))
    assert as_is.cut_frames.tolist() == [10, 11] and as_is.outlier_frames.size == 0


def test_boundary_frames_step_past_outliers():
    """Outliers' scores are those of their stand-ins, so they look steady: the pair steps past them anyway."""
    scores = np.full(40, 1.0)
    scores[0], scores[20] = 0.0, 50.0

    def pair(outliers):
        shots = Shots(np.array([20]), 30.0, 40, scores, "test", np.array(outliers, dtype=np.int64))
        found = boundary_frames(shots, 0)
        return found.before, found.after

    assert pair([]) == (19, 20)
    assert pair([19]) == (18, 20)
    assert pair([20]) == (19, 21)
    assert pair([21, 30]) == (19, 20)
    assert pair([18, 19, 20, 21]) == (17, 22)  # hand-made runs of outliers too


def test_bad_flash_settings():
    with pytest.raises(InputError, match="flash_min_spike"):
        ShotConfig(flash_min_spike=0.0)
    with pytest.raises(InputError, match="flash_isolation"):
        ShotConfig(flash_isolation=0.5)
    with pytest.raises(InputError, match="outlier_frames"):
        Shots(np.array([5]), 30.0, 10, np.zeros(10), "test", np.array([3, 3]))
    with pytest.raises(InputError, match="outlier_frames"):
        Shots(np.array([5]), 30.0, 10, np.zeros(10), "test", np.array([10]))
