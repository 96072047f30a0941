"""Codecs between the data contracts (:mod:`multithumbs.types` and the method's outputs) and artifacts.

A frozen dataclass becomes arrays (its numpy fields; dict-of-array fields nested as ``field/name``) and
JSON attributes (everything else, with the class name), and back. One generic codec serves every
contract, so a new field needs no codec change.
"""

from __future__ import annotations

import dataclasses
import functools
from typing import Any

import numpy as np

CONTRACT_NAMES = ("Shots", "PersonTracks", "CameraTrajectory", "SharedSpace", "WorldResult", "GroundTruth",
                  "AlignedBoundary", "Placement", "Identities", "Matching", "FocalEstimate")
"""The classes an artifact may hold, by name (what ``attributes["contract"]`` records)."""


@functools.cache
def contracts() -> dict[str, type]:
    """Name -> class of every contract. Imported on first use: the method's outputs live beside the method
    (torch), and a run that only checks the store must not import it."""
    from multithumbs.method.align import AlignedBoundary
    from multithumbs.method.reid import Matching
    from multithumbs.method.identities import Identities
    from multithumbs.world_placement import Placement
    from multithumbs.scene.focal import FocalEstimate
    from multithumbs.types import CameraTrajectory, GroundTruth, PersonTracks, SharedSpace, Shots, WorldResult

    classes = {cls.__name__: cls for cls in (Shots, PersonTracks, CameraTrajectory, SharedSpace, WorldResult,
                                             GroundTruth, AlignedBoundary, Placement, Identities, Matching,
                                             FocalEstimate)}
    assert tuple(classes) == CONTRACT_NAMES
    return classes


def _is_contract(value: Any) -> bool:
    return type(value).__name__ in CONTRACT_NAMES


def encode(obj: Any) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """``(arrays, attributes)`` of a contract instance."""
    name = type(obj).__name__
    if name not in CONTRACT_NAMES:
        raise TypeError(f"no codec for {name}; known: {', '.join(sorted(CONTRACT_NAMES))}")
    arrays: dict[str, np.ndarray] = {}
    fields: dict[str, Any] = {}
    for f in dataclasses.fields(obj):
        value = getattr(obj, f.name)
        if isinstance(value, np.ndarray):
            arrays[f.name] = value
        elif _is_contract(value):  # a nested contract (GroundTruth.world)
            sub_arrays, sub_attributes = encode(value)
            arrays.update({f"{f.name}/{k}": v for k, v in sub_arrays.items()})
            fields[f.name] = {"__contract__": sub_attributes}
        elif isinstance(value, tuple) and value and all(isinstance(v, np.ndarray) for v in value):
            arrays.update({f"{f.name}/{i}": v for i, v in enumerate(value)})  # per-shot arrays of any shapes
            fields[f.name] = {"__array_tuple__": len(value)}
        elif isinstance(value, tuple) and value and all(_is_contract(v) for v in value):
            parts = []
            for i, item in enumerate(value):  # per-cut contracts (Identities.matchings)
                sub_arrays, sub_attributes = encode(item)
                arrays.update({f"{f.name}/{i}/{k}": v for k, v in sub_arrays.items()})
                parts.append(sub_attributes)
            fields[f.name] = {"__contract_tuple__": parts}
        elif isinstance(value, dict) and all(isinstance(v, np.ndarray) or np.isscalar(v) for v in value.values()):
            for k, v in value.items():
                arrays[f"{f.name}/{k}"] = np.asarray(v)
            fields[f.name] = {"__arrays__": sorted(value)}
        elif isinstance(value, tuple):
            fields[f.name] = {"__tuple__": list(value)}
        elif isinstance(value, (np.floating, np.integer)):
            fields[f.name] = value.item()
        else:
            fields[f.name] = value
    return arrays, {"contract": name, "fields": fields}


def decode(arrays: dict[str, np.ndarray], attributes: dict[str, Any]) -> Any:
    """Inverse of :func:`encode`."""
    cls = contracts()[attributes["contract"]]
    kwargs: dict[str, Any] = {}
    for f in dataclasses.fields(cls):
        if f.name in arrays:
            kwargs[f.name] = arrays[f.name]
        elif f.name in attributes["fields"]:
            value = attributes["fields"][f.name]
            if isinstance(value, dict) and "__contract__" in value:
                prefix = f"{f.name}/"
                value = decode({k[len(prefix):]: v for k, v in arrays.items() if k.startswith(prefix)},
                               value["__contract__"])
            elif isinstance(value, dict) and "__array_tuple__" in value:
                value = tuple(arrays[f"{f.name}/{i}"] for i in range(value["__array_tuple__"]))
            elif isinstance(value, dict) and "__contract_tuple__" in value:
                value = tuple(decode({k[len(f"{f.name}/{i}/"):]: v for k, v in arrays.items()
                                      if k.startswith(f"{f.name}/{i}/")}, part)
                              for i, part in enumerate(value["__contract_tuple__"]))
            elif isinstance(value, dict) and "__arrays__" in value:
                value = {k: arrays[f"{f.name}/{k}"] for k in value["__arrays__"]}
            elif isinstance(value, dict) and "__tuple__" in value:
                value = tuple(value["__tuple__"])
            kwargs[f.name] = value
    return cls(**kwargs)
