"""What a data root holds: which dataset, its sequences (cameras, people, frames) or edited clips.

:func:`detect_dataset` recognises a root by its layout (DATASETS.md); :func:`describe_root` is what
``multithumbs dataset list`` prints; :func:`open_sequence` opens one capture for the benchmark builder.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from multithumbs.datasets.sequence import MultiViewSequence
from multithumbs.errors import InputError

DATASETS = ("egohumans", "harmony4d", "egobody", "ava", "sitcoms")

_LAYOUTS = ("EgoHumans <activity>/<sequence>/colmap/, Harmony4D {train,test}/<activity>/<sequence>/colmap/, "
            "EgoBody data_info_release.csv, AVA {train,val}/midframes/ or ava_*_v2.2.csv, "
            "sitcoms human_data/ + human_pairs/")


def detect_dataset(root: str | Path) -> str:
    """The dataset a root holds, from its layout (InputError listing the layouts looked for)."""
    root = Path(root)
    if not root.is_dir():
        raise InputError(f"{root}: no such data root folder")
    if (root / "data_info_release.csv").is_file() or (root / "kinect_color").is_dir():
        return "egobody"
    if (root / "human_data").is_dir() or (root / "human_pairs").is_dir():
        return "sitcoms"
    if any((root / split / "midframes").is_dir() for split in ("train", "val")) or any(root.glob("ava_*_v2.2.csv")) \
            or any(root.glob("annotations/ava_*_v2.2.csv")):
        return "ava"
    for split in ("train", "test"):
        if any(p.is_dir() for p in (root / split).glob("*/*/colmap")) or \
                any(p.is_dir() for p in (root / split).glob("*/*/processed_data")):
            return "harmony4d"
    if any(p.is_dir() for p in root.glob("*/*/colmap")) or any(p.is_dir() for p in root.glob("*/*/processed_data")):
        return "egohumans"
    raise InputError(f"{root}: not a data root this version reads (looked for {_LAYOUTS})")


def open_sequence(data_root: str | Path, dataset: str, sequence: str, smpl_dir: str | Path | None = None,
                  bodies=None, fps: float | None = None) -> MultiViewSequence:
    """Open one multi-view capture.

    Args:
        data_root: the dataset's root.
        dataset: ``"egohumans"``, ``"harmony4d"`` or ``"egobody"``.
        sequence: the sequence (recording) name under the root.
        smpl_dir: the user's SMPL models (EgoBody's gendered ground truth).
        bodies: ``gender -> body model`` instead of ``smpl_dir``.
        fps: override the dataset's frame rate.
    """
    root = Path(data_root)
    if not root.is_dir():
        raise InputError(f"{root}: no such data root folder")
    if dataset in ("egohumans", "harmony4d"):
        from multithumbs.datasets.egohumans import load_egohumans

        return load_egohumans(root, sequence, dataset=dataset, fps=fps)
    if dataset == "egobody":
        from multithumbs.datasets.egobody import gendered_bodies, load_egobody

        if bodies is None and smpl_dir is not None:
            bodies = gendered_bodies(smpl_dir)
        return load_egobody(root, sequence, bodies=bodies, fps=fps)
    raise InputError(f"dataset: {dataset!r} is not a multi-view capture (expected egohumans, harmony4d or egobody)")


def describe_root(root: str | Path, dataset: str | None = None) -> dict[str, Any]:
    """JSON-ready description of a data root (``multithumbs dataset list``)."""
    root = Path(root)
    kind = dataset or detect_dataset(root)
    if kind not in DATASETS:
        raise InputError(f"--dataset: expected one of {', '.join(DATASETS)}, got {kind!r}")
    out: dict[str, Any] = {"dataset": kind, "root": str(root)}
    if kind in ("egohumans", "harmony4d"):
        from multithumbs.datasets.egohumans import find_sequences, load_egohumans

        names = find_sequences(root, kind)
        if not names:
            raise InputError(f"{root}: no {kind} sequence folder found")
        out["sequences"] = [load_egohumans(root, name, dataset=kind).describe() for name in names]
    elif kind == "egobody":
        from multithumbs.datasets.egobody import find_recordings, load_egobody, read_splits

        splits = read_splits(root)
        out["sequences"] = []
        for name in find_recordings(root):
            entry = load_egobody(root, name).describe()
            entry["split"] = splits.get(name)
            out["sequences"].append(entry)
    elif kind == "ava":
        from multithumbs.datasets.edited import describe_ava

        out.update(describe_ava(root))
    else:
        from multithumbs.datasets.edited import describe_sitcoms

        out.update(describe_sitcoms(root))
    return out


__all__ = ["DATASETS", "describe_root", "detect_dataset", "open_sequence"]
