"""Model files taken out of a registry package at setup: where they live, whether they are the checked
bytes, and how they are written.

BlazePose's two files come out of MediaPipe's wheel (:mod:`.blazepose_models`) and NanoDet's out of an npm
package (:mod:`.nanodet`). Each is known by its SHA-256; a file with other bytes counts as missing, and an
install writes each file under a temporary name first, so an interrupted one leaves nothing half-written.
Nothing is downloaded at run time.
"""

from __future__ import annotations

import hashlib
import os
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from multithumbs.errors import InputError


@dataclass(frozen=True)
class PackagedModel:
    """Which files a model needs and where they come from."""

    label: str
    """How error messages name what needs the files, e.g. ``"perception backend 'blazepose'"``."""
    env_var: str
    """Environment variable that names the files' folder instead of the default."""
    folder_name: str
    """Default folder: ``<venv>/share/multithumbs/<folder_name>``."""
    files: dict[str, tuple[str, str]]
    """File name -> (member of the package's archive, SHA-256)."""
    install_command: str
    """The command that installs the files, for error messages."""


def model_folder(model: PackagedModel) -> Path:
    """``$<env_var>`` when set, else ``<venv>/share/multithumbs/<folder_name>``."""
    configured = os.environ.get(model.env_var)
    return Path(configured) if configured else Path(sys.prefix) / "share" / "multithumbs" / model.folder_name


def missing_files(model: PackagedModel, folder: Path | None = None) -> list[str]:
    """Names of the files absent from ``folder`` (default :func:`model_folder`) or not the expected bytes."""
    folder = folder or model_folder(model)
    return [name for name, (_, digest) in model.files.items()
            if not (folder / name).is_file() or hashlib.sha256((folder / name).read_bytes()).hexdigest() != digest]


def check_files(model: PackagedModel, folder: Path | None = None) -> Path:
    """The folder, or :class:`InputError` naming what is missing and the command that installs it."""
    folder = folder or model_folder(model)
    missing = missing_files(model, folder)
    if missing:
        raise InputError(f"{model.label}: {', '.join(missing)} missing or damaged in {folder}; "
                         f"install with {model.install_command}")
    return folder


def write_files(model: PackagedModel, folder: Path, read_member: Callable[[str], bytes], source: str) -> None:
    """Write every file, read from the package by ``read_member(member)``, into ``folder``, each checked
    against its SHA-256 before it is written (``source`` names the package in errors)."""
    contents = {}
    for name, (member, digest) in model.files.items():
        try:
            contents[name] = read_member(member)
        except KeyError:
            raise InputError(f"{source}: no {member}") from None
        if hashlib.sha256(contents[name]).hexdigest() != digest:
            raise InputError(f"{source}: {member} is not the file this project was checked with (SHA-256 differs)")
    folder.mkdir(parents=True, exist_ok=True)
    for name, content in contents.items():
        with tempfile.NamedTemporaryFile(dir=folder, prefix=f".{name}.", delete=False) as partial:
            partial.write(content)
        os.chmod(partial.name, 0o644)  # a temporary file is the owner's alone; the model is everyone's
        Path(partial.name).replace(folder / name)


__all__ = ["PackagedModel", "model_folder", "missing_files", "check_files", "write_files"]
