"""Shot detection on real footage: OpenCV's sample videos from Debian's opencv-doc package.

The package is fetched at test time with ``apt-get download`` into the cache folder (never committed);
the tests skip when the fetch fails (no network, no apt).
"""

from pathlib import Path

import pytest

from multithumbs.scene.shots import detect_shots

MEGAMIND_HARD_CUTS = [98, 154, 200]  # checked by eye: three hard cuts; frame 0 is black (the clip's lead-in)


@pytest.fixture(scope="module")
def samples(opencv_samples) -> Path:
    return opencv_samples


@pytest.mark.slow
@pytest.mark.parametrize("detector", ["adaptive", "content"])
def test_real_footage(samples, detector):
    from multithumbs.scene.shots import ShotConfig

    config = ShotConfig(detector=detector)
    for continuous in ("vtest.avi", "tree.avi"):
        if (samples / continuous).is_file():
            assert detect_shots(samples / continuous, config).cut_frames.size == 0, continuous
    shots = detect_shots(samples / "Megamind.avi", config)
    assert set(MEGAMIND_HARD_CUTS) <= set(shots.cut_frames.tolist())
    assert shots.cut_frames.tolist() == MEGAMIND_HARD_CUTS
    assert shots.outlier_frames.size == 0


@pytest.fixture(scope="module")
def megamind_corrupted(samples) -> set[int]:
    """Frames of ``Megamind_bugy.avi`` unlike ``Megamind.avi``'s (over 300 pixels off by more than 60)."""
    import numpy as np

    from multithumbs.video import iter_frames

    if not (samples / "Megamind_bugy.avi").is_file():
        pytest.skip("opencv-doc does not ship Megamind_bugy.avi here")
    pairs = zip(iter_frames(samples / "Megamind_bugy.avi"), iter_frames(samples / "Megamind.avi"))
    return {t for t, (bad, good) in enumerate(pairs)
            if (np.abs(bad.astype(np.int16) - good).max(axis=-1) > 60).sum() > 300}


@pytest.mark.slow
@pytest.mark.parametrize("detector", ["adaptive", "content", "histogram"])
def test_real_footage_with_corrupted_frames(samples, megamind_corrupted, detector):
    """``Megamind_bugy.avi`` is ``Megamind.avi`` with blocks and bars pasted on about every fifth frame
    of 5-120 (23 frames, some small): the same cuts (the old detectors cut at the bar on frame 40 and moved
    the cut at 98 to 101), most corrupted frames found and no other, no boundary frame corrupted."""
    from multithumbs.scene.shots import ShotConfig, boundary_frames

    assert len(megamind_corrupted) == 23
    shots = detect_shots(samples / "Megamind_bugy.avi", ShotConfig(detector=detector))
    assert shots.cut_frames.tolist() == MEGAMIND_HARD_CUTS
    found = set(shots.outlier_frames.tolist())
    assert found <= megamind_corrupted and len(found) >= 18
    for c in range(shots.cut_frames.size):
        pair = boundary_frames(shots, c)
        assert not {pair.before, pair.after} & megamind_corrupted
