"""A Prefect server and workers on loopback for the deployment tests; everything started is stopped."""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import time
import urllib.error
import urllib.request
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
PREFECT = str(Path(sys.executable).with_name("prefect"))


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


# The server answers 503 for errors a client may retry (a busy SQLite database); Prefect's own client
# retries 429, 502 and 503 with backoff (prefect/client/base.py, PrefectHttpxAsyncClient), so REST calls
# made here do the same instead of failing a test on a momentarily locked database.
RETRYABLE = {429, 502, 503}
REQUEST_TIMEOUT = 60.0
"""Seconds a call may wait for the server: Prefect's own client default (PREFECT_API_REQUEST_TIMEOUT). The
server answers a read late while its SQLite database is busy with a running flow's writes (seen at 30 s
on a loaded 2-core machine); a GET that times out is retried like a 503, being safe to repeat."""


def call_api(url: str, method: str = "GET", body: dict | None = None, attempts: int = 6):
    """JSON from a REST call to the Prefect API, retried with backoff on the codes Prefect's client retries
    (and, for a GET, on a timeout)."""
    request = urllib.request.Request(url, method=method, data=None if body is None else json.dumps(body).encode(),
                                     headers={"Content-Type": "application/json"})
    for attempt in range(attempts):
        try:
            with urllib.request.urlopen(request, timeout=REQUEST_TIMEOUT) as response:
                text = response.read()
            return json.loads(text) if text else None
        except urllib.error.HTTPError as error:
            if error.code not in RETRYABLE or attempt == attempts - 1:
                raise
        except TimeoutError:
            if method != "GET" or attempt == attempts - 1:
                raise
        time.sleep(min(2.0 ** attempt, 10.0))


def healthy(url: str) -> bool:
    try:
        with urllib.request.urlopen(f"{url}/health", timeout=2) as response:
            return response.status == 200
    except OSError:
        return False


def stop(process: subprocess.Popen, sig: int) -> None:
    """Stop a process group politely (``sig``), then for sure; the worker stops on SIGINT, not SIGTERM."""
    if process.poll() is None:
        os.killpg(process.pid, sig)
        try:
            process.wait(timeout=30)
        except subprocess.TimeoutExpired:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait(timeout=10)


class Stack:
    """``env`` for the prefect CLI, ``start`` a long-running prefect command, ``prefect`` a short one,
    ``api`` for REST calls; :meth:`close` stops everything started, last first."""

    def __init__(self, tmp_path: Path, **env: str):
        self.port = free_port()
        self.api_url = f"http://127.0.0.1:{self.port}/api"
        self.env = {**os.environ, "PREFECT_HOME": str(tmp_path / "prefect_home"), "PREFECT_API_URL": self.api_url,
                    "PREFECT_SERVER_ANALYTICS_ENABLED": "false", "COLUMNS": "250", "PREFECT_LOGGING_LEVEL": "WARNING",
                    "MULTITHUMBS_HOME": str(REPO), "MULTITHUMBS_CACHE": str(tmp_path / "cache"), **env}
        self.logs = tmp_path / "logs"
        self.logs.mkdir(exist_ok=True)
        self.started: list[tuple[subprocess.Popen, int]] = []

    def start(self, name: str, *args: str, sig: int) -> subprocess.Popen:
        process = subprocess.Popen([PREFECT, *args], env=self.env, cwd=REPO, start_new_session=True,
                                   stdout=open(self.logs / f"{name}.log", "w"), stderr=subprocess.STDOUT)
        self.started.append((process, sig))
        return process

    def start_server(self, timeout: float = 120) -> subprocess.Popen:
        server = self.start("server", "server", "start", "--host", "127.0.0.1", "--port", str(self.port),
                            sig=signal.SIGTERM)
        deadline = time.time() + timeout
        while not healthy(self.api_url):
            assert server.poll() is None, (self.logs / "server.log").read_text()
            assert time.time() < deadline, "server did not become healthy"
            time.sleep(1)
        return server

    def start_worker(self, pool: str, name: str = "worker") -> subprocess.Popen:
        return self.start(name, "worker", "start", "--pool", pool, sig=signal.SIGINT)

    def prefect(self, *args: str, timeout: float = 120, cwd: Path = REPO) -> str:
        done = subprocess.run([PREFECT, *args], env=self.env, cwd=cwd, capture_output=True, text=True,
                              timeout=timeout)
        assert done.returncode == 0, f"prefect {' '.join(args)}:\n{done.stdout}\n{done.stderr}"
        return done.stdout

    def api(self, method: str, path: str, body: dict | None = None):
        return call_api(f"{self.api_url}{path}", method, body)

    def flow_runs(self, deployment_id: str) -> list[dict]:
        return self.api("POST", "/flow_runs/filter", {"deployments": {"id": {"any_": [deployment_id]}}})

    def close(self) -> None:
        for process, sig in reversed(self.started):
            stop(process, sig)
        assert all(process.poll() is not None for process, _ in self.started)
