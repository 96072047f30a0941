"""The CLI's Prefect API (flows/local_api.py): a server a command starts is kept for the next command, never
stopped under a command using it, and stops by itself once idle; ``MULTITHUMBS_API_LINGER=0`` stops it with
the command. Real servers (each ~5 s to start), no flow."""

import os
import sys
import time

import pytest

from flows import local_api


@pytest.fixture
def home(tmp_path, monkeypatch):
    """A Prefect home for this test; Prefect hidden from start_api (the test process imported it, which
    would make start_api leave the API to Prefect), PREFECT_API_URL restored afterwards."""
    monkeypatch.delitem(sys.modules, "prefect", raising=False)
    api_url = os.environ.pop("PREFECT_API_URL", None)  # start_api sets it: restored by hand below
    home = tmp_path / "prefect"
    home.mkdir()
    monkeypatch.setenv("PREFECT_HOME", str(home))
    for name, value in (("PREFECT_SERVER_ANALYTICS_ENABLED", "false"), ("DO_NOT_TRACK", "1"),
                        ("PREFECT_LOGGING_LEVEL", "WARNING")):  # as the CLI's flow_environment
        monkeypatch.setenv(name, value)
    try:
        yield home
    finally:
        local_api.stop_kept(home)
        os.environ.pop("PREFECT_API_URL", None)
        if api_url is not None:
            os.environ["PREFECT_API_URL"] = api_url


def _until(condition, seconds: float) -> bool:
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(0.2)
    return condition()


@pytest.mark.skipif(local_api.fcntl is None, reason="keeping a server needs POSIX locks")
def test_a_server_is_kept_for_the_next_command_and_stops_once_idle(home, monkeypatch):
    monkeypatch.setenv(local_api.LINGER_ENV, "1")
    first = local_api.start_api(home)
    assert first.source == "kept (started)"
    first.wait(120)
    first.stop()  # the command ends: its server stays for the next
    assert local_api.healthy(first.api_url)

    del os.environ["PREFECT_API_URL"]  # the next command is another process
    second = local_api.start_api(home)
    assert (second.source, second.api_url) == ("kept", first.api_url)
    second.wait(5)
    # Idle for longer than the linger time, but a command holds the lease: the server stays.
    time.sleep(1 + 2 * local_api.POLL_SECONDS + 1)
    assert local_api.healthy(second.api_url)
    second.stop()
    assert _until(lambda: not local_api.healthy(first.api_url), 1 + 3 * local_api.POLL_SECONDS + 20)
    assert not (home / local_api.KEPT_FILE).exists()


@pytest.mark.skipif(local_api.fcntl is None, reason="keeping a server needs POSIX locks")
def test_stopping_a_kept_server_waits_for_the_command_using_it(home, monkeypatch):
    """What `multithumbs dashboard` and the benchmark do: the record goes at once (the next command starts
    its own server), the server when the command using it ends."""
    monkeypatch.setenv(local_api.LINGER_ENV, "600")
    api = local_api.start_api(home)
    api.wait(120)
    assert local_api.stop_kept(home, timeout=1 + local_api.POLL_SECONDS)
    assert not (home / local_api.KEPT_FILE).exists() and local_api.healthy(api.api_url)
    api.stop()
    assert _until(lambda: not local_api.healthy(api.api_url), 20)
    assert not local_api.stop_kept(home)


def test_linger_0_stops_the_server_with_the_command(home, monkeypatch):
    monkeypatch.setenv(local_api.LINGER_ENV, "0")
    api = local_api.start_api(home)
    assert api.source == "ephemeral" and api.process.poll() is None
    process = api.process
    api.stop()
    assert process.poll() is not None and not (home / local_api.KEPT_FILE).exists()


def test_a_bad_linger_is_one_line(monkeypatch):
    monkeypatch.setenv(local_api.LINGER_ENV, "ten minutes")
    with pytest.raises(RuntimeError, match="MULTITHUMBS_API_LINGER='ten minutes'"):
        local_api.linger_seconds()
    monkeypatch.setenv(local_api.LINGER_ENV, "-1")
    with pytest.raises(RuntimeError):
        local_api.linger_seconds()
    monkeypatch.delenv(local_api.LINGER_ENV)
    assert local_api.linger_seconds() == local_api.DEFAULT_LINGER


def test_a_stale_record_is_not_used(home, monkeypatch):
    """A record whose keeper is gone (killed with SIGKILL, say) names no server: a new one is started."""
    import json

    monkeypatch.setenv(local_api.LINGER_ENV, "0")
    (home / local_api.KEPT_FILE).write_text(json.dumps({"api_url": "http://127.0.0.1:9/api", "pid": 2 ** 22 + 17,
                                                        "runtime": local_api.runtime_identity()}))
    assert local_api.kept_server(home) is None
    api = local_api.start_api(home)
    assert api.source == "ephemeral"
    api.stop()
