import numpy as np
import pytest

from multithumbs.errors import InputError
from multithumbs.synth.files import write_video
from multithumbs.video import iter_frames, probe_video, read_frames


@pytest.fixture(scope="module")
def clip(tmp_path_factory):
    frames = np.zeros((7, 48, 64, 3), np.uint8)
    for i in range(7):
        frames[i, :, :, i % 3] = 40 * i
    return write_video(tmp_path_factory.mktemp("video") / "clip.mp4", frames, 12.0), frames


def test_probe_counts_frames(clip):
    info = probe_video(clip[0])
    assert (info.num_frames, info.width, info.height, info.image_size) == (7, 64, 48, (48, 64))
    assert info.fps == pytest.approx(12.0)


def test_read_frames_in_asked_order(clip):
    path, truth = clip
    got = read_frames(path, [5, 1, 5])
    assert got.shape == (3, 48, 64, 3)
    means = got.reshape(3, -1, 3).mean(1)
    assert np.allclose(means, truth[[5, 1, 5]].reshape(3, -1, 3).mean(1), atol=6)
    assert len(list(iter_frames(path, 2, 4))) == 2
    assert read_frames(path).shape[0] == 7


def test_errors_name_the_file(tmp_path, clip):
    with pytest.raises(InputError, match="no such video"):
        probe_video(tmp_path / "missing.mp4")
    bad = tmp_path / "bad.mp4"
    bad.write_bytes(b"not a video at all")
    with pytest.raises(InputError, match="bad.mp4"):
        probe_video(bad)
    with pytest.raises(InputError, match="beyond the end"):
        read_frames(clip[0], [3, 9])


def test_empty_and_zero_frame_videos(tmp_path):
    empty = tmp_path / "empty.mp4"
    empty.write_bytes(b"")
    with pytest.raises(InputError, match="empty"):
        probe_video(empty)
    import cv2

    path = tmp_path / "zero.avi"
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 10.0, (32, 24))
    writer.release()
    with pytest.raises(InputError, match="zero.avi"):
        probe_video(path)
