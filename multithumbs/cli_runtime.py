"""What the CLI's flow commands share: the embedded Prefect API's settings, the API itself, the log file,
the one-line refusal and the end of the process. Imports neither Prefect nor torch (the flows do)."""

from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import Optional

from multithumbs.errors import InputError


def cache_dir() -> Path:
    return Path(os.environ.get("MULTITHUMBS_CACHE", Path.home() / ".cache" / "multithumbs"))


def flow_environment() -> None:
    """Settings of the embedded Prefect API (ephemeral server, SQLite) kept out of the home folder."""
    os.environ.setdefault("PREFECT_HOME", str(cache_dir() / "prefect"))
    # Prefect's server does not create a missing PREFECT_HOME's parents: it then fails to open its SQLite
    # file and the client waits out its whole startup timeout.
    Path(os.environ["PREFECT_HOME"]).mkdir(parents=True, exist_ok=True)
    os.environ.setdefault("PREFECT_SERVER_EPHEMERAL_STARTUP_TIMEOUT_SECONDS", "90")
    # No usage data leaves a user's machine unasked: the embedded server's analytics and Prefect's
    # client-side telemetry (with its first-run notice) are off unless the user sets these themselves.
    os.environ.setdefault("PREFECT_SERVER_ANALYTICS_ENABLED", "false")
    os.environ.setdefault("DO_NOT_TRACK", "1")
    os.environ.setdefault("PREFECT_LOGGING_LEVEL", "WARNING")


_LOG_FILE: Optional[Path] = None
LOGS_KEPT = 20


def log_file() -> Path:
    """This command's log file (created on first write): Prefect's logs and the traceback of a failure.
    One per command under MULTITHUMBS_CACHE/logs; the oldest beyond ``LOGS_KEPT`` are removed."""
    import time

    global _LOG_FILE
    if _LOG_FILE is None:
        folder = cache_dir() / "logs"
        folder.mkdir(parents=True, exist_ok=True)
        for old in sorted(folder.glob("*.log"))[:-LOGS_KEPT]:
            old.unlink(missing_ok=True)
        _LOG_FILE = folder / f"{time.strftime('%Y%m%d-%H%M%S')}-{os.getpid()}.log"
    return _LOG_FILE


_API = None  # the Prefect API of this command's flows (flows.local_api.LocalAPI), once started


def start_flow_api() -> None:
    """Find or start the flows' Prefect API now, before Prefect and torch are imported, so a server starts
    while they import (flows/local_api.py says why); a dashboard on the CLI's Prefect home (``multithumbs
    dashboard``) is used when it runs, else the server an earlier command kept (``MULTITHUMBS_API_LINGER``
    seconds after it, default 600; 0: this command's server stops with it)."""
    from flows.local_api import start_api

    global _API
    try:
        _API = start_api(Path(os.environ["PREFECT_HOME"]), log_file())
    except RuntimeError as exc:  # MULTITHUMBS_API_LINGER is not a number of seconds
        raise InputError(str(exc)) from None
    with open(log_file(), "a", encoding="utf-8") as fh:
        fh.write(f"Prefect API: {_API.source} at {_API.api_url}\n")


def flow_logging() -> None:
    """After the flows are imported: Prefect's logs (tracebacks of failed tasks) to :func:`log_file`, so a
    failure inside a flow prints one line, like one before it; then wait for the API to answer."""
    from flows.logs import log_to_file

    log_to_file(log_file())
    if _API is not None:
        try:
            _API.wait(float(os.environ.get("PREFECT_SERVER_EPHEMERAL_STARTUP_TIMEOUT_SECONDS", "90")))
        except RuntimeError as exc:
            raise InputError(f"Prefect API: {exc}") from None


def refuse(message: str, exc: BaseException) -> None:
    """One line on stderr naming the input and the problem (and the log holding the traceback); exit 2."""
    import traceback

    path = log_file()
    try:
        with open(path, "a", encoding="utf-8") as fh:
            fh.write("".join(traceback.format_exception(exc)))
        where = f" (details: {path})"
    except OSError:
        where = ""
    print(f"error: {message}{where}", file=sys.stderr)
    sys.exit(2)


def finish(code) -> None:
    """End the process with ``code`` (an exit code, None or a message), stopping a server it started (or
    handing a kept one back to its keeper).

    Once torch or Prefect is imported, the process ends with ``os._exit`` after atexit handlers have run and
    output is flushed: tearing down the interpreter after torch, Prefect and its server modules took ~5 s
    here, and there is nothing left to do in it.
    """
    if isinstance(code, str):
        print(code, file=sys.stderr)
        code = 1
    code = 0 if code is None else code
    if not {"prefect", "torch"} & set(sys.modules):
        if _API is not None:
            _API.stop()
        sys.exit(code)
    import atexit
    import logging

    atexit._run_exitfuncs()  # Prefect's log and event workers drain to the API here: stop the server after
    if _API is not None:
        _API.stop()
    logging.shutdown()
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)
