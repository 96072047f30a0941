"""The store against an S3-compatible server on loopback (moto), through the same code as a local folder."""

import socket
import subprocess
import sys
import time

import numpy as np
import pytest

from storage.keys import artifact_key
from storage.store import ArtifactStore

pytest.importorskip("moto")
s3fs = pytest.importorskip("s3fs")


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


@pytest.fixture(scope="module")
def s3_endpoint():
    port = _free_port()
    server = subprocess.Popen([sys.executable, "-m", "moto.server", "-H", "127.0.0.1", "-p", str(port)],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    url = f"http://127.0.0.1:{port}"
    try:
        for _ in range(100):
            try:
                socket.create_connection(("127.0.0.1", port), timeout=0.2).close()
                break
            except OSError:
                time.sleep(0.1)
        options = {"key": "test", "secret": "test", "client_kwargs": {"endpoint_url": url, "region_name": "us-east-1"}}
        import boto3

        boto3.client("s3", endpoint_url=url, aws_access_key_id="test", aws_secret_access_key="test",
                     region_name="us-east-1").create_bucket(Bucket="artifacts-bucket")
        yield options
    finally:
        server.terminate()
        server.wait(10)


def test_store_round_trip_on_s3(s3_endpoint):
    store = ArtifactStore("s3://artifacts-bucket/multithumbs", **s3_endpoint)
    key = artifact_key("align", 1, {"a": 1}, [])
    arrays = {"transl": np.random.default_rng(0).normal(size=(2, 40, 3)), "valid": np.ones((2, 40), bool)}
    store.write(key, "align", arrays, {"note": "s3"})
    again = ArtifactStore("s3://artifacts-bucket/multithumbs", **s3_endpoint)
    assert again.exists(key) and again.keys() == [key]
    loaded, attrs = again.read(key)
    np.testing.assert_array_equal(loaded["transl"], arrays["transl"])
    assert attrs == {"note": "s3"}
    assert again.gc(keep=[]) == [key] and not again.exists(key)
