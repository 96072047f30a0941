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
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import smplx
import torch
from smplx.lbs import vertices2joints
from smplx.utils import Struct

# Reading SMPL files (numpy .npz checked, chumpy pickles converted) lives in smpl_files; re-exported here.
from multithumbs.body.smpl_files import _read_npz, convert_smpl_pickle, read_smpl_pickle  # noqa: F401
# The posing algebra (Rodrigues coordinate-major, the kinematic tree by levels) lives in kinematics.
from multithumbs.body.kinematics import _KinematicLevels, rodrigues_coordinate_major  # noqa: F401
from multithumbs.conventions import NUM_BETAS, NUM_BODY_JOINTS, NUM_JOINTS
from multithumbs.determinism import fix_threads
from multithumbs.body.paths import MODEL_ENV_VAR, resolve_model_path  # noqa: F401  (re-exported)
from multithumbs.errors import InputError

SMPL_NUM_VERTICES = 6890
SMPL_FOOT_VERTEX_IDS = np.array([3216, 3387, 6617, 6787])
"""SMPL's left big toe, left heel, right big toe, right heel (smplx's ``vertex_ids['smplh']``)."""

VERTICES_PER_CALL = 4_000_000
"""Poses per ``smplx`` call are capped so that a call handles about this many vertices (bounds memory)."""



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
        # These products round by torch's thread count: with two threads they differed in the last bits and
        # every body fitted with the model after them did too, so `bench --workers 1` (the body loaded before
        # any stage pinned the count) and `--workers 2` stored different bytes under one key.
        fix_threads()
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
