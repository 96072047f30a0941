"""The blazepose perception source: per-shot PersonTracks from frames, and through load_perception."""

from pathlib import Path

import cv2
import numpy as np
import pytest

from multithumbs.perception.blazepose_models import missing_models
from multithumbs.types import PersonTracks, Shots

FIXTURES = Path(__file__).parent / "fixtures"
pytestmark = pytest.mark.skipif(bool(missing_models()), reason="BlazePose models not installed (scripts/setup.sh)")


@pytest.fixture(scope="module")
def frame():
    return cv2.cvtColor(cv2.imread(str(FIXTURES / "s09_frame63.png")), cv2.COLOR_BGR2RGB)


def test_tracks_of_a_still_clip_follow_its_person_in_every_frame(frame, body):
    from multithumbs.perception.blazepose_backend import blazepose_tracks
    from multithumbs.scene.two_view import default_intrinsics

    frames = [frame] * 8 + [np.zeros_like(frame)] * 6  # a cut to black: nobody in the second shot
    shots = Shots(np.array([8]), 24.0, 14, np.zeros(14), "given")
    K = default_intrinsics(frame.shape[1], frame.shape[0])
    calls = []
    tracks, seconds = blazepose_tracks(iter(frames), shots, K, body, progress=lambda *a: calls.append(a))
    assert [tr.shot_index for tr in tracks] == [0, 1]
    first, second = tracks
    assert isinstance(first, PersonTracks) and first.num_people >= 1
    assert first.valid.all(axis=1).any()  # someone seen in all 8 frames of a still clip
    assert second.num_people == 0 and second.valid.shape == (0, 6)
    np.testing.assert_array_equal(first.K, K)
    # the fitted body stands in front of the camera where the 2D keypoints are
    person = int(np.flatnonzero(first.valid.all(axis=1))[0])
    assert 1.0 < first.transl[person, 0, 2] < 20.0
    confident = first.keypoints2d[person, 0, :, 2] > 0.5
    assert confident.sum() >= 8
    assert first.masks[person].any()
    assert seconds.frames == 14 and seconds.detector_calls > 0 and seconds.landmark_calls >= 8
    assert calls[-1] == (1, 6, 6) and (0, 8, 8) in calls


def test_load_perception_defaults_to_nobody_on_frames_without_people(tmp_path, body):
    from multithumbs.perception import DEFAULT_SPEC, load_perception
    from multithumbs.synth.files import write_video

    frames = np.full((10, 120, 200, 3), 90, np.uint8)
    path = write_video(tmp_path / "empty.mp4", frames, 24.0)
    shots = Shots(np.array([5]), 24.0, 10, np.zeros(10), "given")
    tracks = load_perception(DEFAULT_SPEC, path, shots, body=body)
    assert DEFAULT_SPEC == "blazepose"
    assert [tr.num_people for tr in tracks] == [0, 0]


def test_blazepose_takes_no_options():
    from multithumbs.errors import InputError
    from multithumbs.perception import check_backends, parse_spec

    with pytest.raises(InputError, match="blazepose takes no options"):
        check_backends(parse_spec("blazepose:fast"))
    check_backends(parse_spec("blazepose"))
