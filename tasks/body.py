"""Which body model the stages pose people with, and what of it their artifact keys hash.

A stage that poses bodies (synthesis, alignment, propagation, post-processing) takes the model's path
as a plain argument and the model's identity in its parameters: ``{"body": sha256 of the file}`` for a
user's SMPL file, nothing for the procedural body. So the keys change when the file's bytes change (not
when it moves), and the procedural body's keys are those it always had.
"""

from __future__ import annotations

from pathlib import Path


def resolve_body(smpl_model: str | Path | None) -> tuple[str | None, dict]:
    """``(path or None, key parameters)`` of the model a flow was asked for.

    ``smpl_model`` else ``$MULTITHUMBS_SMPL_MODEL`` else the procedural body, as
    :func:`multithumbs.body.paths.resolve_model_path` decides; resolved once in the flow, so every task
    of a run poses the same file. Raises :class:`~multithumbs.errors.InputError` for a missing file.
    """
    from multithumbs.body.paths import resolve_model_path
    from storage.keys import file_digest

    path, source = resolve_model_path(smpl_model)
    if source == "procedural":
        return None, {}
    return str(path), {"body": file_digest(path)}


def without_body(params: dict) -> dict:
    """A stage's parameters minus the body's identity (what the stage's own code reads)."""
    return {k: v for k, v in params.items() if k != "body"}
