"""Native libraries that write straight to file descriptor 2, past ``sys.stderr``: their lines held
back while they load, and only what the caller lets through written out. Standard library only: the
package's first import (:mod:`multithumbs.cpu_kernels`) uses it before numpy is loaded."""

from __future__ import annotations

import contextlib
import os
import sys
import tempfile
from typing import Callable, Iterator


@contextlib.contextmanager
def native_stderr_held(let_through: Callable[[str, bool], str]) -> Iterator[None]:
    """Hold file descriptor 2 for the block; then write ``let_through(held_text, failed)`` to stderr,
    ``failed`` telling whether the block raised (which it still does)."""
    sys.stderr.flush()
    saved = os.dup(2)
    with tempfile.TemporaryFile() as held:
        os.dup2(held.fileno(), 2)
        failed = False
        try:
            yield
        except BaseException:
            failed = True
            raise
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            held.seek(0)
            sys.stderr.write(let_through(held.read().decode(errors="replace"), failed))


__all__ = ["native_stderr_held"]
