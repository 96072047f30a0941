"""A method variant's configuration with a user's JSON overrides applied (``--set section.field=value``).

Kept out of :mod:`tasks.method` (which imports Prefect) so the CLI can refuse a bad ``--set`` before the
flow's modules are imported.
"""

from __future__ import annotations

import dataclasses
import json
from typing import Any, Sequence


METHOD_SECTIONS = ("align", "reid", "post")
"""Sub-configs of :class:`multithumbs.pipeline.MethodConfig` that overrides may name."""


def parse_assignments(assignments: Sequence[str], flag: str = "--set") -> dict:
    """``section.field=value`` texts (JSON values; a value that is not JSON stays a string) as the overrides
    :func:`method_config` takes, e.g. ``["reid.max_distance=0.8"]`` -> ``{"reid": {"max_distance": 0.8}}``.
    A name without a section is a top-level field of ``MethodConfig``."""
    from multithumbs.errors import InputError

    overrides: dict = {}
    for text in assignments:
        name, sep, value = text.partition("=")
        if not sep or not name:
            raise InputError(f"{flag} {text!r}: expected section.field=value, e.g. reid.max_distance=0.8")
        try:
            parsed = json.loads(value)
        except ValueError:
            parsed = value
        section, dot, field = name.partition(".")
        if dot:
            overrides.setdefault(section, {})[field] = parsed
        else:
            overrides[section] = parsed
    return overrides


def method_config(variant: str = "full", overrides: dict[str, Any] | None = None):
    """The :class:`~multithumbs.pipeline.MethodConfig` of a variant with JSON overrides applied.

    ``overrides`` maps a section (``align``, ``reid``, ``post``) to ``{field: value}``, or a top-level field
    of ``MethodConfig`` to its value, e.g. ``{"reid": {"max_distance": 0.8}, "appearance_window": 9}``.
    Unknown names raise :class:`~multithumbs.errors.InputError`.
    """
    from multithumbs.errors import InputError
    from multithumbs.method.config import variant_config

    config = variant_config(variant)
    for name, value in (overrides or {}).items():
        if name in METHOD_SECTIONS:
            section = getattr(config, name)
            known = {f.name: f for f in dataclasses.fields(section)}
            for field_name, field_value in value.items():
                if field_name not in known:
                    raise InputError(f"method parameter {name}.{field_name}: unknown; known: {', '.join(known)}")
            section = dataclasses.replace(section, **{k: tuple(v) if isinstance(v, list) else v
                                                      for k, v in value.items()})
            config = dataclasses.replace(config, **{name: section})
        elif name in {f.name for f in dataclasses.fields(config)} and name != "variant":
            config = dataclasses.replace(config, **{name: value})
        else:
            raise InputError(f"method parameter {name}: unknown; sections {', '.join(METHOD_SECTIONS)} or a "
                             f"MethodConfig field")
    return config
