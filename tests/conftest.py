import os
import shutil
import subprocess
from pathlib import Path

import pytest

import multithumbs  # noqa: F401  (first: it pins the CPU kernels before numpy and torch load)


@pytest.fixture(scope="session", autouse=True)
def _isolated_cache(tmp_path_factory):
    """Generated files (the procedural body) go to a per-session cache, never the home folder."""
    if "MULTITHUMBS_CACHE" not in os.environ:
        os.environ["MULTITHUMBS_CACHE"] = str(tmp_path_factory.mktemp("cache"))
    # The CLI commands tests run stop their Prefect server with them: a kept one (flows/local_api.py) would
    # outlive the test by ten minutes. The tests of keeping set it themselves.
    os.environ.setdefault("MULTITHUMBS_API_LINGER", "0")
    yield


@pytest.fixture(scope="session")
def body(_isolated_cache):
    from multithumbs.body.model import load_body_model

    return load_body_model()


OPENCV_SAMPLES = "usr/share/doc/opencv-doc/examples/data"


@pytest.fixture(scope="session")
def opencv_samples() -> Path:
    """OpenCV's sample videos from Debian's opencv-doc (fetched once with apt-get into the cache; skips
    when that fails)."""
    cache = Path(os.environ.get("MULTITHUMBS_CACHE", Path.home() / ".cache" / "multithumbs")) / "opencv-doc"
    target = cache / "x" / OPENCV_SAMPLES
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


