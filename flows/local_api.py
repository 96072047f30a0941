"""The Prefect API a CLI run talks to, found or started without importing Prefect (stdlib only).

Left to itself, the first ``flow()`` call of a process imports Prefect's whole server in the CLI process
(~5 s here: fastapi, SQLAlchemy models, docket) only to spawn the ephemeral server, then waits for that
server to import the same modules again and start (~8 s), one after the other, after the CLI's own imports
(torch, the flows) are done. :func:`start_api` starts the same ephemeral server (the command and
environment of ``prefect.server.api.server.SubprocessASGIServer``, Prefect 3.8.8) before the CLI imports
anything heavy, so the server starts while the CLI imports; the flow then goes through it as before.

When a dashboard started by ``multithumbs dashboard`` serves the same Prefect home, the run goes to it
instead: no server to start, and the run shows in that dashboard. An exported ``PREFECT_API_URL`` (a
server of deploy/README.md) is always used as it is.
"""

from __future__ import annotations

import atexit
import json
import os
import signal
import socket
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

DASHBOARD_FILE = "multithumbs-dashboard.json"
"""In PREFECT_HOME while ``multithumbs dashboard`` runs: ``{"url": ..., "pid": ...}``."""


def healthy(api_url: str, timeout: float = 1.0) -> bool:
    """Whether the Prefect API at ``api_url`` (``http://host:port/api``) answers its health check."""
    try:
        with urllib.request.urlopen(f"{api_url}/health", timeout=timeout) as response:
            return response.status == 200
    except (OSError, ValueError):
        return False


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def dashboard_url(prefect_home: Path) -> str | None:
    """The API of the dashboard serving ``prefect_home``, if one is running and healthy."""
    try:
        record = json.loads((prefect_home / DASHBOARD_FILE).read_text())
    except (OSError, ValueError):
        return None
    url = record.get("api_url")
    return url if isinstance(url, str) and healthy(url, timeout=0.5) else None


class LocalAPI:
    """A Prefect API for this process: given (``PREFECT_API_URL``, a dashboard) or started here."""

    def __init__(self, api_url: str | None, process: subprocess.Popen | None, source: str):
        self.api_url, self.process, self.source = api_url, process, source

    def wait(self, timeout: float) -> None:
        """Block until the API answers; RuntimeError (one line) if the server died or never answered."""
        if self.api_url is None:
            return
        deadline = time.monotonic() + timeout
        while not healthy(self.api_url):
            if self.process is not None and self.process.poll() is not None:
                raise RuntimeError(f"the Prefect API server exited with code {self.process.returncode} before "
                                   f"answering at {self.api_url}")
            if time.monotonic() > deadline:
                raise RuntimeError(f"the Prefect API at {self.api_url} did not answer within {timeout:.0f} s")
            time.sleep(0.1)

    def stop(self) -> None:
        """Stop a server started here (SIGTERM: uvicorn shuts down cleanly, SQLite is left consistent)."""
        if self.process is not None and self.process.poll() is None:
            self.process.send_signal(signal.SIGTERM)
            try:
                self.process.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
        self.process = None


def start_api(prefect_home: Path, log_path: Path | None = None) -> LocalAPI:
    """The API this process's flows should use, set as ``PREFECT_API_URL`` (call before importing Prefect).

    ``PREFECT_API_URL`` already set: used. A dashboard on ``prefect_home`` running: used. Otherwise an
    ephemeral server (no UI, no background services) starts on a free loopback port with its output in
    ``log_path``; :meth:`LocalAPI.wait` before the first flow call, :meth:`LocalAPI.stop` at the end.
    """
    given = os.environ.get("PREFECT_API_URL")
    if given:
        return LocalAPI(given, None, "PREFECT_API_URL")
    if "prefect" in sys.modules:
        # Imported already (a test calling the app in-process): its settings are fixed and it will start
        # its own ephemeral server; one started here would never be used.
        return LocalAPI(None, None, "prefect's own")
    url = dashboard_url(prefect_home)
    if url:
        os.environ["PREFECT_API_URL"] = url
        return LocalAPI(url, None, "dashboard")
    port = free_port()
    # As SubprocessASGIServer._run_uvicorn_command: no UI, the ephemeral set of services, the final app.
    env = {**os.environ, "PREFECT_UI_ENABLED": "0", "PREFECT__SERVER_EPHEMERAL": "1", "PREFECT__SERVER_FINAL": "1"}
    output = open(log_path, "ab") if log_path is not None else subprocess.DEVNULL
    try:
        process = subprocess.Popen(
            [sys.executable, "-m", "uvicorn", "--factory", "prefect.server.api.server:create_app",
             "--host", "127.0.0.1", "--port", str(port), "--log-level", "error", "--lifespan", "on"],
            env=env, stdout=output, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)
    finally:
        if output is not subprocess.DEVNULL:
            output.close()
    url = f"http://127.0.0.1:{port}/api"
    os.environ["PREFECT_API_URL"] = url
    api = LocalAPI(url, process, "ephemeral")
    atexit.register(api.stop)  # the CLI stops it itself; this covers callers that do not
    return api


def serve_dashboard(prefect_home: Path, host: str, port: int, announce=print) -> int:
    """Run ``prefect server start`` (UI and API) on ``prefect_home`` until it stops (Ctrl-C); while it runs,
    the CLI's flows go to it (:func:`start_api`), so they show in its dashboard. Returns its exit code."""
    api_url = f"http://{host}:{port}/api"
    if healthy(api_url, timeout=0.5):
        raise RuntimeError(f"something already answers at {api_url}; pick another --port")
    record = prefect_home / DASHBOARD_FILE
    prefect_home.mkdir(parents=True, exist_ok=True)
    env = {**os.environ, "PREFECT_HOME": str(prefect_home)}
    env.pop("PREFECT_API_URL", None)
    process = subprocess.Popen([str(Path(sys.executable).with_name("prefect")), "server", "start", "--host", host,
                                "--port", str(port)], env=env, stdin=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 120
        while not healthy(api_url):
            if process.poll() is not None:
                return process.returncode
            if time.monotonic() > deadline:
                raise RuntimeError(f"the dashboard's server did not answer at {api_url} within 120 s")
            time.sleep(0.5)
        record.write_text(json.dumps({"api_url": api_url, "pid": process.pid}))
        announce(f"dashboard at http://{host}:{port} on PREFECT_HOME={prefect_home}; `multithumbs run` and "
                 f"`multithumbs demo` send their runs here while it runs (Ctrl-C stops it)")
        return process.wait()
    except KeyboardInterrupt:
        process.send_signal(signal.SIGINT)  # the server shuts down cleanly on SIGINT or SIGTERM
        return process.wait(timeout=30)
    finally:
        record.unlink(missing_ok=True)
        if process.poll() is None:
            process.terminate()
            process.wait(timeout=30)
