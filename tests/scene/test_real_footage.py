"""Shot detection on real footage: OpenCV's sample videos from Debian's opencv-doc package.

The package is fetched at test time with ``apt-get download`` into the cache folder (never committed);
the tests skip when the fetch fails (no network, no apt).
"""

import os
import shutil
import subprocess
from pathlib import Path

import pytest

from multithumbs.scene.shots import detect_shots

DATA = "usr/share/doc/opencv-doc/examples/data"
MEGAMIND_HARD_CUTS = [98, 154, 200]  # checked by eye: three hard cuts; frame 0 is black (the clip's lead-in)


@pytest.fixture(scope="module")
def samples() -> Path:
    cache = Path(os.environ.get("MULTITHUMBS_CACHE", Path.home() / ".cache" / "multithumbs")) / "opencv-doc"
    target = cache / "x" / DATA
    if (target / "vtest.avi").is_file() and (target / "Megamind.avi").is_file():
        return target
    if shutil.which("apt-get") is None or shutil.which("dpkg") is None:
        pytest.skip("apt-get/dpkg not available to fetch opencv-doc")
    cache.mkdir(parents=True, exist_ok=True)
    try:
        subprocess.run(["apt-get", "download", "opencv-doc"], cwd=cache, check=True, capture_output=True, timeout=300)
        debs = sorted(cache.glob("opencv-doc_*.deb"))
        subprocess.run(["dpkg", "-x", str(debs[-1]), str(cache / "x")], check=True, capture_output=True, timeout=300)
    except (subprocess.SubprocessError, IndexError, OSError) as exc:
        pytest.skip(f"could not fetch opencv-doc: {exc.__class__.__name__}")
    if not (target / "vtest.avi").is_file():
        pytest.skip("opencv-doc does not ship the sample videos here")
    return target


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
