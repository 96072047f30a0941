"""The body model: smplx's SMPL over a user's SMPL file or a procedural SMPL-format body.

The names below are imported on first use (PEP 562): finding the model's file
(:mod:`multithumbs.body.paths`) imports neither torch nor smplx.
"""

from __future__ import annotations

import importlib

_EXPORTS = {
    "model": ("BodyModel", "BodyOutput", "load_body_model"),
    "procedural": ("PROCEDURAL_MODEL_VERSION", "build_procedural_smpl", "procedural_model_path",
                   "write_procedural_smpl"),
}
_WHERE = {name: module for module, names in _EXPORTS.items() for name in names}

__all__ = ["BodyModel", "BodyOutput", "PROCEDURAL_MODEL_VERSION", "build_procedural_smpl",
           "load_body_model", "procedural_model_path", "write_procedural_smpl"]


def __getattr__(name: str):
    if name not in _WHERE:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f"{__name__}.{_WHERE[name]}"), name)
    globals()[name] = value
    return value
