import os

import pytest

from multithumbs.synth.scene import SceneConfig

TINY = SceneConfig(name="tiny", num_people=2, num_shots=2, num_frames=10, seed=41, image_size=(180, 320),
                   cut_angle_deg=30)


@pytest.fixture(scope="session")
def prefect(tmp_path_factory):
    """One Prefect test harness (a temporary API and database) for every flow test: it takes ~15 s to start."""
    os.environ.setdefault("PREFECT_HOME", str(tmp_path_factory.mktemp("prefect")))
    os.environ.setdefault("PREFECT_SERVER_EPHEMERAL_STARTUP_TIMEOUT_SECONDS", "90")
    from prefect.testing.utilities import prefect_test_harness

    with prefect_test_harness(server_startup_timeout=120):
        yield
