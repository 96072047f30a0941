import os

import pytest


@pytest.fixture(scope="session", autouse=True)
def _isolated_cache(tmp_path_factory):
    """Generated files (the procedural body) go to a per-session cache, never the home folder."""
    if "MULTITHUMBS_CACHE" not in os.environ:
        os.environ["MULTITHUMBS_CACHE"] = str(tmp_path_factory.mktemp("cache"))
    yield


@pytest.fixture(scope="session")
def body(_isolated_cache):
    from multithumbs.body.model import load_body_model

    return load_body_model()
