"""Reading SMPL files: a numpy ``.npz`` checked array by array, and an official ``.pkl`` (chumpy arrays, a
Python 2 pickle) read without chumpy and converted to ``.npz`` (:func:`convert_smpl_pickle`).
"""

from __future__ import annotations

import pickle
from pathlib import Path

import numpy as np

from multithumbs.body.procedural import write_npz
from multithumbs.conventions import NUM_BETAS, NUM_BODY_JOINTS, NUM_JOINTS
from multithumbs.errors import InputError

_REQUIRED = ("v_template", "shapedirs", "posedirs", "J_regressor", "weights", "kintree_table", "f")
"""The arrays ``smplx.SMPL`` needs."""


def convert_smpl_pickle(source: str | Path, destination: str | Path) -> Path:
    """Convert an official SMPL ``.pkl`` (chumpy arrays, Python 2 pickle) to a plain numpy ``.npz``.

    chumpy does not run on current Python; this reads its pickled arrays without it (chumpy ``Ch``
    objects become their ``x`` array, scipy sparse matrices become dense) and writes the arrays
    ``smplx.SMPL`` needs. Point ``$MULTITHUMBS_SMPL_MODEL`` at the result.
    """
    arrays = read_smpl_pickle(source)
    arrays["f"] = arrays["f"].astype(np.int64)
    arrays["kintree_table"] = arrays["kintree_table"].astype(np.int64)
    arrays["kintree_table"][0, 0] = -1
    return write_npz(destination, arrays)


def read_smpl_pickle(path: str | Path) -> dict[str, np.ndarray]:
    """The arrays ``smplx.SMPL`` needs from an SMPL pickle, read without chumpy (``Ch`` objects -> their
    ``x`` arrays, scipy sparse -> dense); :class:`InputError` for a broken or foreign file."""
    path = Path(path)
    try:
        with open(path, "rb") as file:
            data = _ChumpyFreeUnpickler(file, encoding="latin1").load()
    except Exception as error:  # pickle raises many types for a broken or foreign file
        raise InputError(f"SMPL model {path}: cannot be read as a pickle ({type(error).__name__}: {error})") from None
    if not isinstance(data, dict):
        raise InputError(f"SMPL model {path}: expected a pickled dict of arrays, got {type(data).__name__}")
    arrays = {}
    for key in _REQUIRED:
        if key not in data:
            raise InputError(f"SMPL model {path}: has no {key!r} array")
        value = data[key]
        arrays[key] = np.asarray(value.toarray() if hasattr(value, "toarray") else _plain(value))
    return arrays


def _plain(value):
    """A chumpy stand-in's array, or the value itself."""
    return value.state.get("x") if isinstance(value, _PickledObject) else value


class _PickledObject:
    """Stand-in for classes of modules that cannot be imported (chumpy): keeps the pickled state."""

    state: dict = {}

    def __setstate__(self, state):
        self.state = state if isinstance(state, dict) else {"state": state}


class _PickledCsc(_PickledObject):
    """Stand-in for a pickled scipy ``csc_matrix`` of any scipy version, rebuilt densely."""

    layout = "csc"

    def toarray(self) -> np.ndarray:
        import scipy.sparse

        s = self.state
        matrix = scipy.sparse.csr_matrix if self.layout == "csr" else scipy.sparse.csc_matrix
        return matrix((s["data"], s["indices"], s["indptr"]), shape=tuple(s.get("_shape", s.get("shape")))).toarray()


class _PickledCsr(_PickledCsc):
    layout = "csr"


class _ChumpyFreeUnpickler(pickle.Unpickler):
    def find_class(self, module: str, name: str):
        if module.split(".")[0] == "chumpy":
            return _PickledObject
        if module.startswith("scipy.sparse") and name in ("csc_matrix", "csr_matrix"):
            return _PickledCsr if name == "csr_matrix" else _PickledCsc
        return super().find_class(module, name)


def _read_npz(path: Path) -> dict[str, np.ndarray]:
    """The arrays of a numpy SMPL file, checked."""
    try:
        with np.load(path, allow_pickle=False) as npz:
            arrays = {key: npz[key] for key in npz.files}
    except Exception as error:  # zipfile/numpy raise many types for a broken file
        raise InputError(f"SMPL model {path}: not a readable numpy .npz file ({error})") from None
    missing = [key for key in _REQUIRED if key not in arrays]
    if missing:
        raise InputError(f"SMPL model {path}: missing arrays {missing} (an SMPL .npz needs {list(_REQUIRED)})")
    n = arrays["v_template"].shape[0] if arrays["v_template"].ndim == 2 else -1
    expected = {"v_template": (n, 3), "J_regressor": (NUM_JOINTS, n), "weights": (n, NUM_JOINTS),
                "kintree_table": (2, NUM_JOINTS)}
    for key, shape in expected.items():
        if arrays[key].shape != shape or n < 1:
            raise InputError(f"SMPL model {path}: {key} has shape {arrays[key].shape}, expected {shape}")
    if arrays["shapedirs"].ndim != 3 or arrays["shapedirs"].shape[:2] != (n, 3) or arrays["shapedirs"].shape[2] < NUM_BETAS:
        raise InputError(f"SMPL model {path}: shapedirs has shape {arrays['shapedirs'].shape}, "
                         f"expected ({n}, 3, >= {NUM_BETAS})")
    if arrays["posedirs"].shape != (n, 3, 9 * NUM_BODY_JOINTS):
        raise InputError(f"SMPL model {path}: posedirs has shape {arrays['posedirs'].shape}, "
                         f"expected ({n}, 3, {9 * NUM_BODY_JOINTS})")
    faces = arrays["f"]
    if faces.ndim != 2 or faces.shape[1] != 3 or faces.size == 0 or faces.min() < 0 or faces.max() >= n:
        raise InputError(f"SMPL model {path}: f must be (F, 3) vertex indices below {n}")
    return arrays
