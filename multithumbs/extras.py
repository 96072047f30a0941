"""Packages that ``pip install -e .`` does not install, and the one-line error saying how to get them.

scripts/setup.sh installs these with ``--no-deps``: each requires ``opencv-python`` (the GUI build), which
would overwrite ``opencv-contrib-python-headless``'s ``cv2`` (/work/shared/DEPENDENCIES.md), so they cannot be
ordinary dependencies in pyproject.toml. A command that needs one checks with :func:`require` before doing
any work; :func:`missing_package_message` turns an import that fails later into the same line.
"""

from __future__ import annotations

import importlib.util

from multithumbs.errors import InputError

SETUP_ONLY = {
    # module: (distribution, the pip command scripts/setup.sh runs for it)
    "scenedetect": ("scenedetect", "pip install --no-deps scenedetect==0.7.2"),
    "depth_anything_3": ("depth-anything-3", "pip install --no-deps depth-anything-3==0.1.1"),
    "trackeval": ("trackeval", "pip install --no-deps trackeval==1.3.0"),
}


def missing_package_message(module: str, needed_for: str | None = None) -> str | None:
    """The one-line message for a missing setup-only ``module`` (None when it is not one of them)."""
    top = module.split(".")[0]
    if top not in SETUP_ONLY:
        return None
    distribution, command = SETUP_ONLY[top]
    purpose = f"{needed_for} needs" if needed_for else "this command needs"
    return (f"{purpose} the {distribution} package, which `pip install -e .` does not install; install it with "
            f"`{command}` (scripts/setup.sh does)")


def is_installed(module: str) -> bool:
    """Whether ``module`` can be imported, without importing it (cheap: no package code runs)."""
    try:
        return importlib.util.find_spec(module) is not None
    except (ImportError, ValueError):
        return False


def require(module: str, needed_for: str) -> None:
    """Raise :class:`InputError` naming the package and its install command when ``module`` is missing."""
    if not is_installed(module):
        raise InputError(missing_package_message(module, needed_for)
                         or f"{needed_for} needs the {module} package, which is not installed")
