"""Prefect's logs of a CLI run go to a file, not the terminal.

Prefect prints every failed task and flow with its full traceback (80-90 lines for one bad input) before
the CLI's own one-line error. For a command-line user the one line is the message; the traceback belongs
in a file the line names. :func:`log_to_file` moves every console handler Prefect installed (at ``import
prefect``) onto one file, and catches Python warnings there too. Deployed runs (workers) are not affected:
only the CLI calls it.
"""

from __future__ import annotations

import logging
import sys
from pathlib import Path

import prefect  # noqa: F401  (configures Prefect's logging; the handlers replaced below exist after it)

_FORMAT = "%(asctime)s %(levelname)-7s %(name)s: %(message)s"


def _is_console(handler: logging.Handler) -> bool:
    stream = getattr(handler, "stream", None)
    return isinstance(handler, logging.StreamHandler) and not isinstance(handler, logging.FileHandler) and \
        stream in (sys.stderr, sys.stdout, sys.__stderr__, sys.__stdout__)


def log_to_file(path: str | Path, level: int = logging.INFO) -> logging.Handler:
    """Send Prefect's console logging (and Python warnings) to ``path`` at ``level``; returns the handler."""
    handler = logging.FileHandler(path, delay=True, encoding="utf-8")
    handler.setFormatter(logging.Formatter(_FORMAT))
    handler.setLevel(level)
    ours = ("prefect", "uvicorn", "fastapi")
    names = [None, *[n for n in logging.root.manager.loggerDict if n.split(".")[0] in ours]]
    for name in names:
        logger = logging.getLogger(name)
        consoles = [h for h in logger.handlers if _is_console(h)]
        for h in consoles:
            logger.removeHandler(h)
        if consoles or name is None:
            logger.addHandler(handler)
    # The file holds the run's story (task states, retries), not only the failures the console showed.
    logging.getLogger("prefect").setLevel(level)
    logging.captureWarnings(True)
    return handler
