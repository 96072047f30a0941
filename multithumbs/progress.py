"""In-process listeners for the progress of long stages (the CLI's bars listen; the flow's tasks report,
beside their Prefect progress artifacts). Pure Python: nothing here knows of Prefect or the CLI."""

from __future__ import annotations

from typing import Callable

Listener = Callable[[str, int, int], None]
"""``listener(label, done, total)``: ``label`` names a run of units (e.g. ``blazepose shot 2/4``)."""
_listeners: list[Listener] = []


def add_listener(listener: Listener) -> None:
    """Call ``listener`` on every report of this process's stages."""
    _listeners.append(listener)


def remove_listener(listener: Listener) -> None:
    if listener in _listeners:
        _listeners.remove(listener)


def notify(label: str, done: int, total: int) -> None:
    """Tell every listener; a listener's failure is its own and never the stage's."""
    for listener in list(_listeners):
        try:
            listener(label, done, total)
        except Exception:  # noqa: BLE001
            pass
