"""The SMPL body model: ``smplx.SMPL`` over a user's SMPL file or the procedural body.

Which file: the ``model_path`` argument, else ``$MULTITHUMBS_SMPL_MODEL``, else the procedural body
(:func:`multithumbs.body.procedural.procedural_model_path`). Every file goes through ``smplx.SMPL``, so
posing is SMPL's own linear blend skinning whichever body is loaded.

Batch rule of :meth:`BodyModel.forward`: ``global_orient``, ``body_pose`` and ``transl`` broadcast
against each other like numpy arrays; ``betas`` are aligned with the LEADING batch dimensions (padded
with trailing singleton dimensions) and then broadcast, because shape belongs to a person, not a frame:
poses ``(P, T, ...)`` with ``betas (P, 10)`` give person ``p`` the shape ``betas[p]`` in every frame;
``betas (10,)`` apply to every pose; ``betas (P, T, 10)`` are per frame.
"""

from __future__ import annotations

import contextlib
import functools
import io
import itertools
import pickle
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import smplx
import torch
from smplx.lbs import vertices2joints
from smplx.utils import Struct

from multithumbs.body.procedural import write_npz
from multithumbs.conventions import NUM_BETAS, NUM_BODY_JOINTS, NUM_JOINTS
from multithumbs.body.paths import MODEL_ENV_VAR, resolve_model_path  # noqa: F401  (re-exported)
from multithumbs.errors import InputError

SMPL_NUM_VERTICES = 6890
SMPL_FOOT_VERTEX_IDS = np.array([3216, 3387, 6617, 6787])
"""SMPL's left big toe, left heel, right big toe, right heel (smplx's ``vertex_ids['smplh']``)."""

VERTICES_PER_CALL = 4_000_000
"""Poses per ``smplx`` call are capped so that a call handles about this many vertices (bounds memory)."""

_REQUIRED = ("v_template", "shapedirs", "posedirs", "J_regressor", "weights", "kintree_table", "f")


@dataclass(frozen=True)
class BodyOutput:
    """A posed body.

    Attributes:
        vertices: ``(..., V, 3)`` mesh vertices (metres, in the frame of ``global_orient``/``transl``).
        joints: ``(..., 24, 3)`` SMPL joints (smplx's first 24), same frame.
    """

    vertices: torch.Tensor
    joints: torch.Tensor


class BodyModel:
    """A loaded SMPL-format body model (``smplx.SMPL`` underneath, in ``self.smpl``).

    Attributes:
        source: ``"procedural"`` or the resolved path of the user's file.
        smpl: the ``smplx.SMPL`` module doing the forward pass.
        dtype: torch dtype of the model; inputs are cast to it.
        faces: ``(F, 3)`` int64 triangles.
        parents: ``(24,)`` int64 kinematic tree (-1 for the root).
        part_labels: ``(V,)`` int64 joint with the largest skinning weight of each vertex.
        num_vertices: ``V``.
        foot_vertex_ids: ``(4,)`` left toe, left heel, right toe, right heel vertices: SMPL's
            ``[3216, 3387, 6617, 6787]`` when ``V == 6890``, else the same landmarks found on the mesh.
        vertex_ids: landmark name -> vertex id handed to ``smplx`` for its extra joints.
        chunk_size: poses per ``smplx`` call (larger batches are split to bound memory).
    """

    def __init__(self, model_path: str | Path | None = None, dtype: torch.dtype = torch.float32):
        path, self.source = resolve_model_path(model_path)
        self.dtype = dtype
        if path.suffix.lower() == ".npz":
            arrays = _read_npz(path)
            vertex_ids = None if len(arrays["v_template"]) == SMPL_NUM_VERTICES else landmark_vertex_ids(
                arrays["v_template"], arrays["weights"], arrays["J_regressor"] @ arrays["v_template"])
            self.smpl = _make_smpl(path, Struct(**arrays), vertex_ids, dtype)
        else:
            self.smpl, vertex_ids = _load_pickled_smpl(path, dtype)
        smpl = self.smpl
        weights = smpl.lbs_weights.double().numpy()
        if vertex_ids is None:  # smplx used SMPL's own landmarks
            vertex_ids = dict(smplx.vertex_ids.vertex_ids["smplh"])
        self.vertex_ids: dict[str, int] = {k: int(v) for k, v in vertex_ids.items()}
        self.faces: np.ndarray = np.asarray(smpl.faces, dtype=np.int64)
        self.parents: np.ndarray = smpl.parents.numpy().astype(np.int64)
        self.part_labels: np.ndarray = weights.argmax(axis=1).astype(np.int64)
        self.num_vertices: int = int(smpl.v_template.shape[0])
        self.foot_vertex_ids: np.ndarray = (
            SMPL_FOOT_VERTEX_IDS.copy() if self.num_vertices == SMPL_NUM_VERTICES else
            np.array([self.vertex_ids[k] for k in ("LBigToe", "LHeel", "RBigToe", "RHeel")]))
        # Poses per smplx call: about VERTICES_PER_CALL vertices at a time.
        self.chunk_size = max(1, VERTICES_PER_CALL // self.num_vertices)
        # Joint regression is linear in the betas: J(β) = J_template + J_shapedirs · β (for joints()).
        regressor = smpl.J_regressor
        self._joint_template = regressor @ smpl.v_template
        self._joint_shapedirs = torch.einsum("jv,vck->jck", regressor, smpl.shapedirs)
        self._chain = _KinematicLevels(self.parents)

    def __repr__(self) -> str:
        return f"BodyModel(source={self.source!r}, vertices={self.num_vertices}, dtype={self.dtype})"

    def _flat_inputs(self, global_orient, body_pose, betas, transl):
        """Check, broadcast (module docstring) and flatten the inputs: ``batch`` and ``(N, k)`` tensors."""
        orient = self._tensor("global_orient", global_orient, (3,))
        pose = self._tensor("body_pose", body_pose, None)
        if pose.shape[-2:] == (NUM_BODY_JOINTS, 3):
            pose = pose.flatten(-2)
        elif pose.ndim == 0 or pose.shape[-1] != 3 * NUM_BODY_JOINTS:
            raise InputError(f"body_pose: expected shape (..., 23, 3) or (..., 69), got {tuple(pose.shape)}")
        shape = self._tensor("betas", betas, (NUM_BETAS,))
        shift = None if transl is None else self._tensor("transl", transl, (3,))

        try:
            batch = torch.broadcast_shapes(orient.shape[:-1], pose.shape[:-1],
                                           *(() if shift is None else (shift.shape[:-1],)))
        except RuntimeError:
            raise InputError(f"global_orient {tuple(orient.shape)}, body_pose {tuple(pose.shape)}"
                             + ("" if shift is None else f", transl {tuple(shift.shape)}")
                             + ": batch shapes do not broadcast") from None
        pad = len(batch) - (shape.ndim - 1)
        if pad > 0:  # person-level betas: align with the leading batch dimensions
            shape = shape.reshape(*shape.shape[:-1], *([1] * pad), NUM_BETAS)
        try:
            batch = torch.broadcast_shapes(batch, shape.shape[:-1])
        except RuntimeError:
            raise InputError(f"betas {tuple(shape.shape)}: batch does not broadcast against the pose "
                             f"batch {tuple(batch)} (betas align with the leading dimensions)") from None

        flat = lambda x: x.expand(*batch, x.shape[-1]).reshape(-1, x.shape[-1])  # noqa: E731
        orient, pose, shape = flat(orient), flat(pose), flat(shape)
        shift = None if shift is None else flat(shift)
        return batch, orient, pose, shape, shift

    def forward(self, global_orient, body_pose, betas, transl=None) -> BodyOutput:
        """Pose the body. Numpy or torch inputs (cast to the model's dtype); torch outputs.

        Args:
            global_orient: ``(..., 3)`` axis-angle rotation of the body about the pelvis joint.
            body_pose: ``(..., 23, 3)`` or ``(..., 69)`` axis-angle joint rotations (SMPL joints 1..23).
            betas: ``(..., 10)`` shape, aligned with the leading batch dimensions (module docstring).
            transl: ``(..., 3)`` translation added to every vertex and joint, or ``None``.
        Returns:
            vertices ``(*B, V, 3)`` and joints ``(*B, 24, 3)``, ``B`` the broadcast batch shape.
            Differentiable with respect to every input.
        """
        batch, orient, pose, shape, shift = self._flat_inputs(global_orient, body_pose, betas, transl)
        n = orient.shape[0]
        if n == 0:
            empty = lambda k: torch.zeros(*batch, k, 3, dtype=self.dtype)  # noqa: E731
            return BodyOutput(empty(self.num_vertices), empty(NUM_JOINTS))
        vertices, joints = [], []
        for start in range(0, n, self.chunk_size):
            part = slice(start, start + self.chunk_size)
            out = self.smpl(global_orient=orient[part], body_pose=pose[part], betas=shape[part],
                            transl=None if shift is None else shift[part])
            vertices.append(out.vertices)
            joints.append(out.joints[:, :NUM_JOINTS])
        cat = lambda xs, k: (xs[0] if len(xs) == 1 else torch.cat(xs)).reshape(*batch, k, 3)  # noqa: E731
        return BodyOutput(cat(vertices, self.num_vertices), cat(joints, NUM_JOINTS))

    __call__ = forward

    def joints(self, global_orient, body_pose, betas, transl=None) -> torch.Tensor:
        """``(*B, 24, 3)`` posed joints without the mesh: the same joints as :meth:`forward`, much faster.

        SMPL's joints are regressed from the shaped template, which is linear in the betas, and then posed
        by the kinematic chain; this evaluates exactly that (smplx's ``batch_rigid_transform`` posing, to
        rounding), skipping the skinning of every vertex. For optimisers that need joints only, so it is
        written for speed: the chain is walked one tree depth at a time (9 steps for SMPL, not 23 joints)
        on 3x3 rotations and joint positions (not 4x4 transforms), with the coordinates leading so every
        op runs on contiguous rows of poses (post-processing's 600 poses: 6 ms forward and backward
        against 16 ms with smplx's ``batch_rodrigues`` and ``batch_rigid_transform``).
        """
        batch, orient, pose, shape, shift = self._flat_inputs(global_orient, body_pose, betas, transl)
        # Coordinate-major (3, 24, N): see rodrigues_coordinate_major.
        rest = self._joint_template.T.unsqueeze(-1) + torch.einsum("jck,nk->cjn", self._joint_shapedirs, shape)
        rest = rest.contiguous()
        rotvecs = torch.cat([orient, pose], dim=-1).reshape(-1, NUM_JOINTS, 3).permute(2, 1, 0).contiguous()
        posed = self._chain.pose(rodrigues_coordinate_major(rotvecs), rest).permute(2, 1, 0)
        posed = posed.contiguous() if shift is None else posed + shift[:, None]
        return posed.reshape(*batch, NUM_JOINTS, 3)

    def rest_joints(self, betas) -> torch.Tensor:
        """``(..., 24, 3)`` joints of the shaped T-pose (zero pose, no translation) for ``betas (..., 10)``."""
        shape = self._tensor("betas", betas, (NUM_BETAS,))
        flat = shape.reshape(-1, NUM_BETAS)
        shaped = self.smpl.forward_shape(betas=flat).v_shaped
        return vertices2joints(self.smpl.J_regressor, shaped).reshape(*shape.shape[:-1], NUM_JOINTS, 3)

    def rest_pelvis(self, betas) -> np.ndarray:
        """``(..., 3)`` float64 rest pelvis (SMPL joint 0, the root's rotation centre) of ``betas (..., 10)``.

        A body's camera-frame pelvis is its SMPL translation plus this point.
        """
        with torch.no_grad():
            return self.rest_joints(betas)[..., 0, :].double().numpy()

    def _tensor(self, name: str, value, trailing: tuple[int, ...] | None) -> torch.Tensor:
        """``value`` as a tensor of the model's dtype with trailing dimensions ``trailing`` (checked)."""
        if value is None:
            raise InputError(f"{name}: required, got None")
        if not torch.is_tensor(value):
            value = np.asarray(value)
            if not value.flags.writeable:  # torch cannot wrap read-only memory (broadcast views)
                value = value.copy()
        tensor = torch.as_tensor(value)
        if not (tensor.is_floating_point() or tensor.dtype in (torch.int32, torch.int64)):
            raise InputError(f"{name}: expected real numbers, got dtype {tensor.dtype}")
        if trailing is not None and (tensor.ndim < len(trailing) or tuple(tensor.shape[-len(trailing):]) != trailing):
            raise InputError(f"{name}: expected shape (..., {', '.join(map(str, trailing))}), "
                             f"got {tuple(tensor.shape)}")
        return tensor.to(self.dtype)


_SKEW_BASIS = torch.tensor([[0.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0],
                            [0.0, 0.0, 1.0], [0.0, 0.0, 0.0], [-1.0, 0.0, 0.0],
                            [0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
"""``(9, 3)``: ``_SKEW_BASIS @ k`` is ``[k]x = [[0, -z, y], [z, 0, -x], [-y, x, 0]]`` flattened row-major."""


def rodrigues_coordinate_major(rotvec: torch.Tensor) -> torch.Tensor:
    """Axis-angle ``(3, ...)`` to rotation matrices ``(3, 3, ...)``, coordinates leading.

    smplx's ``batch_rodrigues`` to rounding: the same formula ``I + sin θ K + (1 - cos θ) K²`` (here with
    ``K² = k kᵀ - |k|² I``) and the same ``1e-8`` offset in the angle, so a zero vector gives the identity
    with a finite gradient. With the coordinates leading, every op runs on contiguous rows of the batch,
    which is much faster on CPU than batched 3x3 products or reductions over a trailing dimension of 3.
    """
    angle = (rotvec + 1e-8).square().sum(0, keepdim=True).sqrt()
    axis = rotvec / angle
    skew = (_SKEW_BASIS.to(rotvec.dtype) @ axis.reshape(3, -1)).reshape(3, 3, *rotvec.shape[1:])
    outer = axis.unsqueeze(1) * axis.unsqueeze(0)
    eye = torch.eye(3, dtype=rotvec.dtype).reshape(3, 3, *(1,) * (rotvec.ndim - 1))
    # |k| is 1 up to the angle's offset, which smplx's K @ K keeps: so does |k|² here.
    return eye + torch.sin(angle) * skew + (1 - torch.cos(angle)) * (outer - eye * axis.square().sum(0, keepdim=True))


class _KinematicLevels:
    """A kinematic tree walked one depth level at a time (joints of one level are posed together).

    Works coordinate-major (joints on dimension -2, the batch last), see :meth:`pose`. With SMPL's
    breadth-first joint order each level is a contiguous block and most parent lookups are slices.
    """

    def __init__(self, parents: np.ndarray):
        parents = np.asarray(parents, np.int64)
        count = len(parents)
        depth = np.zeros(count, np.int64)
        for j in range(1, count):
            if not 0 <= parents[j] < j:
                raise InputError(f"SMPL model: kinematic tree joint {j} has parent {parents[j]}, "
                                 "expected an earlier joint")
            depth[j] = depth[parents[j]] + 1
        order = np.argsort(depth, kind="stable")
        self.reorder = None if np.array_equal(order, np.arange(count)) else torch.as_tensor(order)
        self.restore = None if self.reorder is None else torch.as_tensor(np.argsort(order))
        has_child = np.zeros(count, bool)
        has_child[parents[1:]] = True
        self.sizes = [int((depth == d).sum()) for d in range(depth.max() + 1)]
        levels = np.split(order, np.cumsum(self.sizes)[:-1])
        # Per level after the root: where each joint's parent sits among the previous level's joints
        # (positions) and among those of them with children (rotations), and which joints have children.
        self.steps = []
        for prev, ids in itertools.pairwise(levels):
            prev_rot = [j for j in prev if has_child[j]]
            self.steps.append((_lookup([list(prev).index(p) for p in parents[ids]]),
                               _lookup([prev_rot.index(p) for p in parents[ids]]),
                               _lookup([i for i, j in enumerate(ids) if has_child[j]])))

    def pose(self, rotations: torch.Tensor, rest: torch.Tensor) -> torch.Tensor:
        """``(3, J, N)`` posed joints from local rotations ``(3, 3, J, N)`` and rest joints ``(3, J, N)``.

        Each level: ``x_j = x_parent + G_parent (r_j - r_parent)`` and, for joints with children,
        ``G_j = G_parent R_j``. The root stays at its rest position (as in smplx's ``batch_rigid_transform``).
        """
        if self.reorder is not None:
            rest, rotations = rest.index_select(-2, self.reorder), rotations.index_select(-2, self.reorder)
        rest_levels = rest.split(self.sizes, dim=-2)
        rotation_levels = rotations.split(self.sizes, dim=-2)
        posed = [rest_levels[0]]
        frames = rotation_levels[0]                       # global rotations of the level's joints with children
        for (pos_of_parent, rot_of_parent, with_children), prev_rest, level_rest, local in zip(
                self.steps, rest_levels[:-1], rest_levels[1:], rotation_levels[1:]):
            parent_rot = rot_of_parent(frames)
            offset = level_rest - pos_of_parent(prev_rest)
            posed.append(pos_of_parent(posed[-1]) + (parent_rot * offset.unsqueeze(0)).sum(1))
            if with_children is not None:
                frames = (with_children(parent_rot).unsqueeze(2) * with_children(local).unsqueeze(0)).sum(1)
        out = torch.cat(posed, dim=-2)
        return out if self.restore is None else out.index_select(-2, self.restore)


def _lookup(index: list[int]):
    """``f(x)`` selecting ``x[..., index, :]`` (a slice or a broadcast where the index allows one);
    None for an empty index."""
    if len(index) == 0:
        return None
    first, count = index[0], len(index)
    if index == list(range(first, first + count)):
        return lambda x: x[..., first:first + count, :]
    if all(i == first for i in index):
        return lambda x: x[..., first:first + 1, :].expand(*x.shape[:-2], count, x.shape[-1])
    positions = torch.as_tensor(index)
    return lambda x: x.index_select(-2, positions)


@functools.lru_cache(maxsize=8)
def _load_cached(path: Path, source: str, mtime_ns: int) -> BodyModel:
    return BodyModel(None if source == "procedural" else path)


def load_body_model(model_path: str | Path | None = None) -> BodyModel:
    """A shared float32 :class:`BodyModel`, cached by resolved path (and the file's modification time)."""
    path, source = resolve_model_path(model_path)
    return _load_cached(path, source, path.stat().st_mtime_ns)


def landmark_vertex_ids(v_template: np.ndarray, weights: np.ndarray, joints: np.ndarray) -> dict[str, int]:
    """Vertices for smplx's extra joints (nose, eyes, ears, toes, heels, finger tips) on any SMPL-format mesh.

    Each landmark is the vertex of the right body part lying furthest in the landmark's direction in the
    rest pose (SMPL body frame: +y up, +z front, +x left).

    Args:
        v_template: ``(V, 3)`` rest vertices.
        weights: ``(V, 24)`` skinning weights (a vertex's part is its largest weight).
        joints: ``(24, 3)`` rest joints.
    Returns:
        the ``vertex_ids`` dict ``smplx.SMPL`` takes (the keys of ``smplx.vertex_ids.vertex_ids['smplh']``).
    """
    v = np.asarray(v_template, float)
    part = np.asarray(weights).argmax(axis=1)

    def extreme(parts: tuple[int, ...], score: np.ndarray) -> int:
        candidates = np.flatnonzero(np.isin(part, parts))
        if candidates.size == 0:  # no such part: the nearest vertex to the part's joint
            return int(np.argmin(np.linalg.norm(v - joints[parts[0]], axis=1)))
        return int(candidates[np.argmax(score[candidates])])

    head = v - joints[15]
    ids = {
        "nose": extreme((15,), head[:, 2] - 2 * np.abs(head[:, 0]) - np.abs(head[:, 1] - 0.03)),
        "reye": extreme((15,), head[:, 2] - np.abs(head[:, 0] + 0.03) - np.abs(head[:, 1] - 0.06)),
        "leye": extreme((15,), head[:, 2] - np.abs(head[:, 0] - 0.03) - np.abs(head[:, 1] - 0.06)),
        "rear": extreme((15,), -head[:, 0] - np.abs(head[:, 1] - 0.03) - np.abs(head[:, 2])),
        "lear": extreme((15,), head[:, 0] - np.abs(head[:, 1] - 0.03) - np.abs(head[:, 2])),
    }
    for side, sign, (ankle, foot, hand) in (("L", 1.0, (7, 10, 22)), ("R", -1.0, (8, 11, 23))):
        toe = v - joints[foot]
        ids[f"{side}BigToe"] = extreme((foot,), toe[:, 2] - 0.5 * sign * toe[:, 0] - toe[:, 1])
        ids[f"{side}SmallToe"] = extreme((foot,), toe[:, 2] + 0.5 * sign * toe[:, 0] - toe[:, 1])
        heel = v - joints[ankle]
        ids[f"{side}Heel"] = extreme((ankle,), -heel[:, 2] - heel[:, 1] - np.abs(heel[:, 0]))
        # Palm down in the T-pose: the thumb points forward (+z), the fingers outward (sign * x).
        finger = v - joints[hand]
        along, across = sign * finger[:, 0], finger[:, 2]
        prefix = side.lower()
        ids[f"{prefix}thumb"] = extreme((hand, hand - 2), across - 0.5 * along)
        for name, offset in (("index", 0.025), ("middle", 0.0), ("ring", -0.02), ("pinky", -0.035)):
            ids[f"{prefix}{name}"] = extreme((hand,), along - 3 * np.abs(across - offset))
    return ids


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


def _make_smpl(path: Path, data: Struct | None, vertex_ids: dict[str, int] | None,
               dtype: torch.dtype) -> smplx.SMPL:
    # smplx prints a warning for models with only 10 shape components (the usual case): keep it quiet.
    with contextlib.redirect_stdout(io.StringIO()):
        return smplx.SMPL(model_path=str(path), data_struct=data, num_betas=NUM_BETAS, vertex_ids=vertex_ids,
                          create_global_orient=False, create_body_pose=False, create_betas=False,
                          create_transl=False, dtype=dtype)


def _load_pickled_smpl(path: Path, dtype: torch.dtype) -> tuple[smplx.SMPL, dict[str, int] | None]:
    """An SMPL ``.pkl`` read by smplx itself, and the landmark ids it needs if its mesh is not SMPL's.

    chumpy pickles (the official files) get a message saying how to convert them.
    """
    try:
        smpl = _make_smpl(path, None, None, dtype)
    except ImportError as error:
        if "chumpy" in str(error):
            raise InputError(
                f"SMPL model {path}: stores chumpy arrays, which cannot be read on this Python; convert it "
                f"once with multithumbs.body.model.convert_smpl_pickle('{path}', 'SMPL.npz') and use the .npz"
            ) from None
        raise InputError(f"SMPL model {path}: cannot be unpickled ({error})") from None
    except Exception as error:  # pickle raises many types for a broken or foreign file
        raise InputError(f"SMPL model {path}: not a readable SMPL pickle ({type(error).__name__}: {error})") from None
    n = smpl.v_template.shape[0]
    if smpl.J_regressor.shape != (NUM_JOINTS, n) or smpl.lbs_weights.shape != (n, NUM_JOINTS):
        raise InputError(f"SMPL model {path}: not a 24-joint SMPL model")
    if n == SMPL_NUM_VERTICES:
        return smpl, None
    # smplx's default landmark ids only fit SMPL's own mesh.
    v_template, weights = smpl.v_template.double().numpy(), smpl.lbs_weights.double().numpy()
    ids = landmark_vertex_ids(v_template, weights, smpl.J_regressor.double().numpy() @ v_template)
    smpl.vertex_joint_selector = smplx.vertex_joint_selector.VertexJointSelector(vertex_ids=ids).to(dtype)
    return smpl, ids


__all__ = ["BodyModel", "BodyOutput", "MODEL_ENV_VAR", "SMPL_FOOT_VERTEX_IDS", "convert_smpl_pickle",
           "landmark_vertex_ids", "load_body_model", "resolve_model_path"]
