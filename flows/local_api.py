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

The server a command starts is kept for the next one: it outlives the command, detached, and stops by itself
once no command has used it for ``MULTITHUMBS_API_LINGER`` seconds (default :data:`DEFAULT_LINGER`; 0 stops
it with the command, as before). Starting it costs ~4-5 s on two cores, most of a re-run served from the
store. A keeper process (:func:`keep`, this file run as a script, stdlib only) owns it: every command using
it holds a shared lock on ``PREFECT_HOME/multithumbs-api.lock`` and touches the file when done; the keeper
stops the server only when the file is older than the linger time and it gets the lock exclusively, so never
under a running command. ``PREFECT_HOME/multithumbs-api.json`` names it (its URL, the keeper's pid, and the
Python and Prefect that run it: another interpreter or an upgraded Prefect starts its own).
"""

from __future__ import annotations

import atexit
import hashlib
import importlib.util
import json
import os
import signal
import socket
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

try:
    import fcntl
except ImportError:  # not POSIX: no shared locks, so a server is not kept
    fcntl = None

DASHBOARD_FILE = "multithumbs-dashboard.json"
"""In PREFECT_HOME while ``multithumbs dashboard`` runs: ``{"url": ..., "pid": ...}``."""
KEPT_FILE = "multithumbs-api.json"
"""In PREFECT_HOME while a kept server runs: ``{"api_url", "pid" (the keeper's), "runtime"}``."""
LEASE_FILE = "multithumbs-api.lock"
"""In PREFECT_HOME: shared-locked by every command using the kept server; its mtime is the last use."""
KEPT_LOG = "multithumbs-api.log"
"""In PREFECT_HOME: the kept server's own output (each new server truncates it)."""
LINGER_ENV = "MULTITHUMBS_API_LINGER"
DEFAULT_LINGER = 600.0
"""Seconds a kept server waits for the next command before it stops."""
POLL_SECONDS = 2.0
"""How often the keeper looks at the lease."""


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


def linger_seconds() -> float:
    """``MULTITHUMBS_API_LINGER`` (seconds a started server is kept after the command), default
    :data:`DEFAULT_LINGER`; RuntimeError (one line) when it is not a number of seconds."""
    text = os.environ.get(LINGER_ENV, "").strip()
    if not text:
        return DEFAULT_LINGER
    try:
        value = float(text)
    except ValueError:
        value = -1.0
    if not value >= 0:
        raise RuntimeError(f"{LINGER_ENV}={text!r}: expected the seconds to keep the Prefect API server after a "
                           f"command (0: stop it with the command)")
    return value


def runtime_identity() -> str:
    """The interpreter, the Prefect installation and the Prefect settings (``PREFECT_*`` variables) a server
    runs with, found without importing Prefect: a kept server is used only by commands with the same."""
    spec = importlib.util.find_spec("prefect")
    origin = spec.origin if spec is not None and spec.origin else ""
    stamp = os.stat(origin).st_mtime_ns if origin else 0
    settings = sorted((k, v) for k, v in os.environ.items() if k.startswith("PREFECT_") and k != "PREFECT_API_URL")
    digest = hashlib.sha256(json.dumps(settings).encode()).hexdigest()[:16]
    return f"{sys.executable}|{origin}|{stamp}|{digest}"


def _alive(pid: int) -> bool:
    try:  # a keeper this process started and that has exited is a zombie until reaped here
        if os.waitpid(pid, os.WNOHANG)[0] == pid:
            return False
    except ChildProcessError:
        pass  # not this process's child
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _read_kept(prefect_home: Path) -> dict | None:
    try:
        record = json.loads((prefect_home / KEPT_FILE).read_text())
    except (OSError, ValueError):
        return None
    ok = isinstance(record, dict) and isinstance(record.get("api_url"), str) and isinstance(record.get("pid"), int)
    return record if ok else None


def kept_server(prefect_home: Path, startup_seconds: float = 120.0) -> dict | None:
    """The record of the kept server on ``prefect_home`` if its keeper runs on this runtime and the server
    answers, or was started less than ``startup_seconds`` ago (then :meth:`LocalAPI.wait` waits for it)."""
    record = _read_kept(prefect_home)
    if record is None or record.get("runtime") != runtime_identity() or not _alive(record["pid"]):
        return None
    if healthy(record["api_url"], timeout=5.0):  # busy with another command's run, it may answer slowly
        return record
    try:
        young = time.time() - (prefect_home / KEPT_FILE).stat().st_mtime < startup_seconds
    except OSError:
        young = False
    return record if young else None  # else a stale record (its pid reused): start another server


class Lease:
    """A command's use of the kept server: a shared lock on :data:`LEASE_FILE` (blocks while a keeper is
    stopping its server), released with the file's mtime set to now (the keeper's idle clock)."""

    def __init__(self, prefect_home: Path):
        self.path = prefect_home / LEASE_FILE
        self._fh = open(self.path, "a")
        fcntl.flock(self._fh, fcntl.LOCK_SH)
        os.utime(self.path)

    def release(self) -> None:
        if self._fh is None:
            return
        try:
            os.utime(self.path)
        except OSError:
            pass
        fcntl.flock(self._fh, fcntl.LOCK_UN)
        self._fh.close()
        self._fh = None


class LocalAPI:
    """A Prefect API for this process: given (``PREFECT_API_URL``, a dashboard), kept from an earlier command
    or started here (kept for the next one when ``lease`` is set)."""

    def __init__(self, api_url: str | None, process: subprocess.Popen | None, source: str,
                 lease: Lease | None = None, keeper_pid: int | None = None):
        self.api_url, self.process, self.source = api_url, process, source
        self.lease, self.keeper_pid = lease, keeper_pid

    def wait(self, timeout: float) -> None:
        """Block until the API answers; RuntimeError (one line) if the server died or never answered."""
        if self.api_url is None:
            return
        deadline = time.monotonic() + timeout
        while not healthy(self.api_url):
            if self.process is not None and self.process.poll() is not None:
                raise RuntimeError(f"the Prefect API server exited with code {self.process.returncode} before "
                                   f"answering at {self.api_url}")
            if self.keeper_pid is not None and not _alive(self.keeper_pid):
                raise RuntimeError(f"the Prefect API server at {self.api_url} stopped before answering (its "
                                   f"output: {KEPT_LOG} in PREFECT_HOME)")
            if time.monotonic() > deadline:
                raise RuntimeError(f"the Prefect API at {self.api_url} did not answer within {timeout:.0f} s")
            time.sleep(0.05)

    def stop(self) -> None:
        """Stop a server started here (SIGTERM: uvicorn shuts down cleanly, SQLite is left consistent), or
        hand a kept one back to its keeper."""
        if self.lease is not None:
            self.lease.release()
            self.lease = None
        if self.process is not None and self.process.poll() is None:
            if self.keeper_pid is None:
                self.process.send_signal(signal.SIGTERM)
                try:
                    self.process.wait(timeout=10)
                except subprocess.TimeoutExpired:
                    self.process.kill()
                    self.process.wait()
        self.process = None


def _server_command(port: int) -> tuple[list[str], dict]:
    """As SubprocessASGIServer._run_uvicorn_command: no UI, the ephemeral set of services, the final app."""
    env = {**os.environ, "PREFECT_UI_ENABLED": "0", "PREFECT__SERVER_EPHEMERAL": "1", "PREFECT__SERVER_FINAL": "1"}
    env.pop("PREFECT_API_URL", None)
    return ([sys.executable, "-m", "uvicorn", "--factory", "prefect.server.api.server:create_app",
             "--host", "127.0.0.1", "--port", str(port), "--log-level", "error", "--lifespan", "on"], env)


def start_api(prefect_home: Path, log_path: Path | None = None) -> LocalAPI:
    """The API this process's flows should use, set as ``PREFECT_API_URL`` (call before importing Prefect).

    ``PREFECT_API_URL`` already set: used. A dashboard on ``prefect_home`` running: used. A server kept by
    an earlier command: used. Otherwise an ephemeral server (no UI, no background services) starts on a free
    loopback port: kept for the next command (the module's docstring) unless :func:`linger_seconds` is 0,
    then with its output in ``log_path``. :meth:`LocalAPI.wait` before the first flow call,
    :meth:`LocalAPI.stop` at the end (a kept server is only released).
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
    linger = linger_seconds()
    if fcntl is not None:
        lease = Lease(prefect_home)  # from here until the command ends, no keeper stops its server
        record = kept_server(prefect_home)
        api = None
        if record is not None:  # kept by an earlier command: used whatever this one's linger
            api = LocalAPI(record["api_url"], None, "kept", lease, record["pid"])
        elif linger > 0:
            api = _start_kept(prefect_home, linger, lease)
        else:
            lease.release()
        if api is not None:
            os.environ["PREFECT_API_URL"] = api.api_url
            atexit.register(api.stop)
            return api
    port = free_port()
    command, env = _server_command(port)
    output = open(log_path, "ab") if log_path is not None else subprocess.DEVNULL
    try:
        process = subprocess.Popen(command, env=env, stdout=output, stderr=subprocess.STDOUT,
                                   stdin=subprocess.DEVNULL)
    finally:
        if output is not subprocess.DEVNULL:
            output.close()
    url = f"http://127.0.0.1:{port}/api"
    os.environ["PREFECT_API_URL"] = url
    api = LocalAPI(url, process, "ephemeral")
    atexit.register(api.stop)  # the CLI stops it itself; this covers callers that do not
    return api


def _start_kept(prefect_home: Path, linger: float, lease: Lease) -> LocalAPI:
    """Start a keeper (:func:`keep`) with its server, detached from this command, and record it."""
    port = free_port()
    with open(prefect_home / KEPT_LOG, "wb") as output:
        keeper = subprocess.Popen([sys.executable, str(Path(__file__).resolve()), "keep", str(prefect_home),
                                   str(port), repr(linger)], stdin=subprocess.DEVNULL, stdout=output,
                                  stderr=subprocess.STDOUT, start_new_session=True, close_fds=True)
    url = f"http://127.0.0.1:{port}/api"
    tmp = prefect_home / f".{KEPT_FILE}.{os.getpid()}"
    tmp.write_text(json.dumps({"api_url": url, "pid": keeper.pid, "runtime": runtime_identity(),
                               "linger": linger}))
    os.replace(tmp, prefect_home / KEPT_FILE)
    return LocalAPI(url, keeper, "kept (started)", lease, keeper.pid)


def stop_kept(prefect_home: Path, timeout: float = 30.0) -> bool:
    """Stop the kept server on ``prefect_home`` (SIGTERM to its keeper: at once unless a command is using it,
    then when that command ends), waiting up to ``timeout`` seconds; whether one was running."""
    record = _read_kept(prefect_home)
    if record is None or not _alive(record["pid"]):
        return False
    os.kill(record["pid"], signal.SIGTERM)
    deadline = time.monotonic() + timeout
    while _alive(record["pid"]) and time.monotonic() < deadline:
        time.sleep(0.05)
    return True


def keep(prefect_home: Path, port: int, linger: float) -> int:
    """The keeper: run the server on ``port`` until it has been idle ``linger`` seconds with no command
    holding the lease, then stop it; returns its exit code. SIGTERM (:func:`stop_kept`) withdraws the record
    at once (new commands start their own server) and stops the server as soon as no command holds the lease;
    a second SIGTERM or SIGINT stops it at once. Stdlib only, like this module."""
    record_path, lease_path = prefect_home / KEPT_FILE, prefect_home / LEASE_FILE
    command, env = _server_command(port)
    server = subprocess.Popen(command, env=env, stdin=subprocess.DEVNULL, cwd=prefect_home)
    asked = []

    def on_term(signum, frame):
        asked.append(signum)
        if len(asked) > 1 or signum == signal.SIGINT:
            raise SystemExit(0)
        _forget(record_path)

    signal.signal(signal.SIGTERM, on_term)
    signal.signal(signal.SIGINT, on_term)
    deadline = time.monotonic()
    try:
        while server.poll() is None:
            if not asked:
                time.sleep(max(0.0, deadline - time.monotonic()))
                deadline = time.monotonic() + POLL_SECONDS
                try:
                    idle = time.time() - lease_path.stat().st_mtime
                except OSError:  # the Prefect home is gone
                    break
                if idle < linger:
                    continue
            fh = open(lease_path, "a")
            try:
                fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                fh.close()
                if asked:
                    time.sleep(0.1)
                continue  # a command is using the server
            # The lock is held until this process exits: a command starting meanwhile waits for it, finds no
            # record and starts its own server.
            _forget(record_path)
            _terminate(server)
            break
    finally:
        _forget(record_path)
        _terminate(server)
    return 0 if server.returncode in (0, None, -signal.SIGTERM) else server.returncode


def _forget(record_path: Path) -> None:
    """Remove the record if it names this keeper (a newer server may have replaced it)."""
    record = _read_kept(record_path.parent)
    if record is not None and record["pid"] == os.getpid():
        record_path.unlink(missing_ok=True)


def _terminate(server: subprocess.Popen) -> None:
    if server.poll() is None:
        server.send_signal(signal.SIGTERM)
        try:
            server.wait(timeout=20)
        except subprocess.TimeoutExpired:
            server.kill()
            server.wait()


def serve_dashboard(prefect_home: Path, host: str, port: int, announce=print) -> int:
    """Run ``prefect server start`` (UI and API) on ``prefect_home`` until it stops (Ctrl-C); while it runs,
    the CLI's flows go to it (:func:`start_api`), so they show in its dashboard. Returns its exit code."""
    api_url = f"http://{host}:{port}/api"
    if healthy(api_url, timeout=0.5):
        raise RuntimeError(f"something already answers at {api_url}; pick another --port")
    record = prefect_home / DASHBOARD_FILE
    prefect_home.mkdir(parents=True, exist_ok=True)
    stop_kept(prefect_home)  # the CLI's runs go to the dashboard now: one server on the database is enough
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


if __name__ == "__main__":  # the keeper, started by _start_kept: keep PREFECT_HOME PORT LINGER
    if len(sys.argv) != 5 or sys.argv[1] != "keep":
        sys.exit("usage: local_api.py keep PREFECT_HOME PORT LINGER_SECONDS")
    sys.exit(keep(Path(sys.argv[2]), int(sys.argv[3]), float(sys.argv[4])))
