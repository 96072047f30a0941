"""Which body file a run poses people with (:func:`resolve_model_path`), without importing torch or smplx:
the CLI and the flows resolve it before, or instead of, loading the model (:mod:`multithumbs.body.model`).
"""

from __future__ import annotations

import os
from pathlib import Path

from multithumbs.body.procedural import procedural_model_path
from multithumbs.errors import InputError

MODEL_ENV_VAR = "MULTITHUMBS_SMPL_MODEL"
"""Environment variable naming the user's SMPL file (``.npz`` or ``.pkl``)."""


def resolve_model_path(model_path: str | Path | None = None) -> tuple[Path, str]:
    """The body file to load and its source label (``"procedural"`` or the resolved path).

    Order: ``model_path``, else ``$MULTITHUMBS_SMPL_MODEL``, else the procedural body (generated into
    the cache on first use). Raises :class:`InputError` if a named file does not exist.
    """
    named = model_path if model_path is not None else os.environ.get(MODEL_ENV_VAR) or None
    if named is None:
        return procedural_model_path().resolve(), "procedural"
    origin = "model_path" if model_path is not None else f"${MODEL_ENV_VAR}"
    path = Path(named).expanduser().resolve()
    if not path.is_file():
        raise InputError(f"{origin}: SMPL model file {path} does not exist")
    if path.suffix.lower() not in (".npz", ".pkl"):
        raise InputError(f"{origin}: SMPL model file {path} must be .npz (numpy) or .pkl, got {path.suffix!r}")
    return path, str(path)
