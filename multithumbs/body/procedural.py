"""A procedural SMPL-format body, generated deterministically (no licensed data needed).

The body is a union of closed tube meshes (torso, neck, head, legs, feet, arms with hands), each swept
along a polyline through SMPL joints with superellipse cross-sections, so that ``smplx.SMPL`` can pose it
like the real model. Everything is in SMPL's body frame (:mod:`multithumbs.conventions`): +y up, the
body faces +z, its left is +x, T-pose arms along +-x, the pelvis joint at the origin for the mean shape,
the soles at ``y = SOLE_HEIGHT`` (within 2 mm) for every shape.

The arrays are the ones ``smplx.SMPL`` reads (``v_template``, ``shapedirs``, ``posedirs``,
``J_regressor``, ``weights``, ``kintree_table``, ``f``) plus ``part_labels`` (the joint whose bone each
vertex is attached to) and ``joint_rest`` (the 24 rest joints). Design choices:

- Shape space: the body is generated from interpretable :class:`Proportions`; ``shapedirs[..., k]`` is
  the symmetric secant ``(body(+1 unit) - body(-1 unit)) / 2`` of proportion :data:`BETA_DIRECTIONS`
  ``[k]``, so ``betas[k] = 1`` is one unit of that proportion and betas in ``[-2, 2]`` stay plausible.
- ``posedirs`` are zeros: no pose-corrective blend shapes (plain linear blend skinning).
- ``J_regressor``: each joint is a convex combination of the ring of vertices around it (the
  cross-section of a tube at that joint), solved to reproduce the rest joint exactly; joints therefore
  move with shape as the surrounding surface does.
- Skinning: each vertex is attached to the joint that owns its stretch of tube; across a joint the
  weight moves smoothly (smoothstep over a window about a bone radius wide) from parent to child.
"""

from __future__ import annotations

import io
import os
import tempfile
import zipfile
from dataclasses import replace
from pathlib import Path

import numpy as np

from multithumbs.conventions import NUM_BETAS, NUM_JOINTS, SMPL_PARENTS
# The body's proportions and its tube surface live in multithumbs.body.tubes; re-exported here.
from multithumbs.body.tubes import (ANKLE_HEIGHT, BETA_DIRECTIONS, NEUTRAL_JOINTS, SOLE_HEIGHT,  # noqa: F401
                                    Proportions, _signed_volume, _skeleton, _smoothstep, _stretch, _surface,
                                    _Tube, _TubeMesh)

PROCEDURAL_MODEL_VERSION = "1"
"""Bump whenever the generated arrays change; it names the cached file."""

def _skinning(tubes: list[_Tube], meshes: list[_TubeMesh], vertices: np.ndarray) -> np.ndarray:
    """``(N, 24)`` skinning weights: each tube stretch to its owner, blended across knots."""
    blocks = []
    for tube, mesh in zip(tubes, meshes):
        s, ks = mesh.axial, mesh.knot_axial
        region = np.searchsorted(ks, s, side="right")  # 0 = start cap ... K = end cap
        w = np.zeros((len(s), NUM_JOINTS))
        w[np.arange(len(s)), np.asarray(tube.owners)[region]] = 1.0
        gaps = np.diff(ks)
        for k, half in enumerate(tube.blend):
            parent, child = tube.owners[k], tube.owners[k + 1]
            if parent == child or half <= 0:
                continue
            # Keep neighbouring blend windows apart.
            half = min(half, *(0.5 * gaps[max(k - 1, 0):k + 1]))
            near = np.abs(s - ks[k]) < half
            sigma = _smoothstep((s[near] - ks[k] + half) / (2 * half))
            w[near] = 0.0
            w[near, parent] = 1.0 - sigma
            w[near, child] = sigma
        blocks.append(w)
    weights = np.concatenate(blocks)

    # The torso's upper flanks follow the collars and its lower flanks the thighs, partly.
    torso = np.zeros(len(vertices), bool)
    torso[:len(meshes[0].vertices)] = True
    x, y = vertices[:, 0], vertices[:, 1]
    joints = _skeleton(Proportions())
    for side, collar, hip in ((1.0, 13, 1), (-1.0, 14, 2)):
        share = 0.7 * _smoothstep((side * x - 0.05) / 0.10) * _smoothstep((y - joints[9, 1] - 0.02) / 0.10)
        share += 0.5 * _smoothstep((side * x - 0.02) / 0.10) * _smoothstep((joints[0, 1] - y) / 0.10)
        share = np.where(torso, share, 0.0)
        target = np.where(y > joints[0, 1], collar, hip)
        weights *= (1.0 - share)[:, None]
        weights[np.arange(len(y)), target] += share
    return weights


def _regressor(tubes: list[_Tube], meshes: list[_TubeMesh], vertices: np.ndarray,
               joints: np.ndarray) -> np.ndarray:
    """``(24, N)`` convex weights reproducing ``joints`` from rings of ``vertices``."""
    regressor = np.zeros((NUM_JOINTS, len(vertices)))
    offset = 0
    for tube, mesh in zip(tubes, meshes):
        for joint, knot in tube.joint_knots:
            ids = offset + mesh.rings[knot]
            ring = vertices[ids]
            # Closest-to-uniform weights w with sum(w) = 1 and ring^T w = joint (min-norm correction).
            uniform = np.full(len(ids), 1.0 / len(ids))
            system = np.vstack([ring.T, np.ones(len(ids))])
            target = np.append(joints[joint], 1.0)
            # rcond drops the (numerically zero) direction normal to the ring's plane, which holds the joint.
            correction = np.linalg.lstsq(system, target - system @ uniform, rcond=1e-9)[0]
            w = uniform + correction
            if w.min() < 0 or np.abs(system @ w - target).max() > 1e-9:
                raise RuntimeError(f"procedural body: joint {joint} is not inside its vertex ring")
            regressor[joint, ids] = w
        offset += len(mesh.vertices)
    return regressor


def body_vertices(proportions: Proportions = Proportions()) -> tuple[np.ndarray, np.ndarray]:
    """Vertices ``(N, 3)`` and rest joints ``(24, 3)`` of the procedural body with ``proportions``.

    The topology (vertex order, faces) is the same for all proportions.
    """
    _, _, vertices = _surface(proportions)
    return vertices, _stretch(_skeleton(proportions), proportions.height)


def build_procedural_smpl() -> dict[str, np.ndarray]:
    """The procedural body as the arrays ``smplx.SMPL`` reads, plus ``part_labels`` and ``joint_rest``.

    Returns:
        ``v_template (N, 3)``, ``shapedirs (N, 3, 10)``, ``posedirs (N, 3, 207)`` zeros,
        ``J_regressor (24, N)``, ``weights (N, 24)``, ``kintree_table (2, 24)`` int64 (row 0 parents,
        -1 for the root; row 1 joint ids), ``f (F, 3)`` int64, ``part_labels (N,)`` int64 (the joint owning
        each vertex's stretch of tube), ``joint_rest (24, 3)``. Floats are float64 rounded to 1e-10 so the
        bytes do not depend on last-bit differences between machines.
    """
    mean = Proportions()
    tubes, meshes, v_template = _surface(mean)
    joint_rest = _stretch(_skeleton(mean), mean.height)
    offsets = np.cumsum([0] + [len(m.vertices) for m in meshes])
    faces = np.concatenate([m.faces + o for m, o in zip(meshes, offsets)])
    for m in meshes:  # every part winds outwards
        if _signed_volume(m.vertices, m.faces) <= 0:
            raise RuntimeError("procedural body: a part winds inwards")

    shapedirs = np.zeros((len(v_template), 3, NUM_BETAS))
    for k, (name, step) in enumerate(BETA_DIRECTIONS):
        base = getattr(mean, name)
        plus = _surface(replace(mean, **{name: base + step}))[2]
        minus = _surface(replace(mean, **{name: base - step}))[2]
        shapedirs[:, :, k] = (plus - minus) / 2.0

    weights = _skinning(tubes, meshes, v_template)
    owners = []
    for tube, mesh in zip(tubes, meshes):
        region = np.searchsorted(mesh.knot_axial, mesh.axial, side="right")
        owners.append(np.asarray(tube.owners)[region])
    regressor = _regressor(tubes, meshes, v_template, joint_rest)
    rounded = lambda a: np.round(a, 10) + 0.0  # noqa: E731 -- "+ 0.0" turns -0.0 into 0.0
    v_template, joint_rest, regressor = rounded(v_template), rounded(joint_rest), rounded(regressor)
    return {
        "v_template": v_template,
        "shapedirs": rounded(shapedirs),
        "posedirs": np.zeros((len(v_template), 3, 9 * (NUM_JOINTS - 1))),
        "J_regressor": regressor,
        "weights": rounded(weights),
        "kintree_table": np.stack([np.array(SMPL_PARENTS), np.arange(NUM_JOINTS)]).astype(np.int64),
        "f": faces.astype(np.int64),
        "part_labels": np.concatenate(owners).astype(np.int64),
        "joint_rest": joint_rest,
    }


def write_npz(path: str | Path, arrays: dict[str, np.ndarray]) -> Path:
    """Write ``arrays`` to an ``.npz`` atomically (temporary file + ``os.replace``), byte-reproducibly.

    ``numpy.savez`` stamps zip entries with the current time; here entries are sorted by name, dated
    1980-01-01 and deflated, so the same arrays always give the same bytes.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.NamedTemporaryFile(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp",
                                     delete=False) as tmp:
        try:
            with zipfile.ZipFile(tmp, "w") as archive:
                for name in sorted(arrays):
                    buffer = io.BytesIO()
                    np.lib.format.write_array(buffer, np.ascontiguousarray(arrays[name]), allow_pickle=False)
                    info = zipfile.ZipInfo(f"{name}.npy", date_time=(1980, 1, 1, 0, 0, 0))
                    info.compress_type = zipfile.ZIP_DEFLATED
                    info.external_attr = 0o644 << 16
                    archive.writestr(info, buffer.getvalue())
            tmp.flush()
            os.fsync(tmp.fileno())
        except BaseException:
            os.unlink(tmp.name)
            raise
    os.chmod(tmp.name, 0o644)
    os.replace(tmp.name, path)
    return path


def write_procedural_smpl(path: str | Path) -> Path:
    """Write :func:`build_procedural_smpl` to ``path`` (``.npz``), atomically; the same bytes every time."""
    return write_npz(path, build_procedural_smpl())


def cache_dir() -> Path:
    """The project's cache directory: ``$MULTITHUMBS_CACHE``, else ``~/.cache/multithumbs``."""
    return Path(os.environ.get("MULTITHUMBS_CACHE") or Path.home() / ".cache" / "multithumbs")


def procedural_model_path() -> Path:
    """Path of the procedural body file in the cache directory, generated on first use."""
    path = cache_dir() / f"procedural_smpl_v{PROCEDURAL_MODEL_VERSION}.npz"
    if not path.is_file():
        write_procedural_smpl(path)
    return path


__all__ = [
    "ANKLE_HEIGHT", "BETA_DIRECTIONS", "NEUTRAL_JOINTS", "PROCEDURAL_MODEL_VERSION", "Proportions",
    "SOLE_HEIGHT", "body_vertices", "build_procedural_smpl", "cache_dir", "procedural_model_path",
    "write_npz", "write_procedural_smpl",
]
