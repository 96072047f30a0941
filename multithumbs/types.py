"""Data contracts between stages (DESIGN §4). Frozen dataclasses of numpy arrays, checked on creation.

Every contract validates its shapes in ``__post_init__`` and raises :class:`InputError` naming the
field, the expected shape and the shape it got. Conventions: :mod:`multithumbs.conventions`.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np

from multithumbs.conventions import NUM_BETAS, NUM_BODY_JOINTS, NUM_JOINTS
from multithumbs.errors import InputError


def check_array(owner: str, name: str, value: Any, shape: tuple, sizes: dict[str, int],
                dtype: str = "f") -> np.ndarray:
    """Check ``value`` against ``shape``, binding symbolic sizes in ``sizes``.

    Args:
        owner: contract name, for the message.
        name: field name, for the message.
        value: array-like.
        shape: tuple of ints (exact size), strings (symbols bound on first use and then
            required to agree) or ``None`` (any size).
        sizes: symbol table shared across the fields of one contract; updated in place.
        dtype: numpy kind the array must have: ``"f"`` float, ``"i"`` integer, ``"b"`` bool,
            ``"u"`` unsigned (uint8 masks).
    Returns:
        the array, as a numpy array.
    """
    arr = np.asarray(value)
    if arr.ndim != len(shape):
        raise InputError(f"{owner}.{name}: expected {len(shape)} dimensions {_fmt(shape)}, "
                         f"got shape {arr.shape}")
    for axis, (want, got) in enumerate(zip(shape, arr.shape)):
        if want is None:
            continue
        if isinstance(want, str):
            bound = sizes.setdefault(want, got)
            if bound != got:
                raise InputError(f"{owner}.{name}: axis {axis} ({want}) has size {got} but "
                                 f"{want} = {bound} elsewhere in {owner}")
        elif want != got:
            raise InputError(f"{owner}.{name}: expected shape {_fmt(shape)}, got {arr.shape}")
    kinds = {"f": "f", "i": "iu", "b": "b", "u": "u"}[dtype]
    if arr.dtype.kind not in kinds:
        if dtype == "f" and arr.dtype.kind in "iu":
            arr = arr.astype(np.float64)
        elif dtype == "i" and arr.size == 0:
            arr = arr.astype(np.int64)
        else:
            raise InputError(f"{owner}.{name}: expected dtype kind {dtype!r}, got {arr.dtype}")
    return arr


def _fmt(shape: tuple) -> str:
    return "(" + ", ".join("*" if s is None else str(s) for s in shape) + ")"


class _Checked:
    """Mixin: run ``SPEC`` checks on the dataclass fields and store the converted arrays."""

    SPEC: dict[str, tuple[tuple, str]] = {}

    def __post_init__(self) -> None:
        sizes: dict[str, int] = {}
        owner = type(self).__name__
        for name, (shape, kind) in self.SPEC.items():
            value = getattr(self, name)
            if value is None:
                continue
            object.__setattr__(self, name, check_array(owner, name, value, shape, sizes, kind))
        self._check_extra(sizes)

    def _check_extra(self, sizes: dict[str, int]) -> None:
        """Cross-field checks beyond shapes; overridden where a contract has them."""

    def arrays(self) -> dict[str, np.ndarray]:
        """The array fields that are set, by name."""
        return {f.name: getattr(self, f.name) for f in fields(self)  # type: ignore[arg-type]
                if isinstance(getattr(self, f.name), np.ndarray)}


@dataclass(frozen=True)
class Shots(_Checked):
    """Shot boundaries of one video.

    Attributes:
        cut_frames: ``(C,)`` int, first frame of each new shot, strictly increasing in ``(0, T)``.
        fps: frames per second of the video.
        num_frames: ``T``, frames in the video.
        scores: ``(T,)`` per-frame detector score (0 where the detector gives none).
        source: which detector produced the cuts (``"scenedetect:adaptive"``, ``"ground_truth"``...).
        outlier_frames: ``(F,)`` int, strictly increasing in ``[0, T)``: one-frame outliers (a glitched
            or flashed frame unlike both neighbours) the detector was shown a neighbour in place of;
            boundary frames avoid them. Empty when none were found or looked for (given cuts).
    """

    cut_frames: np.ndarray
    fps: float
    num_frames: int
    scores: np.ndarray
    source: str = "unknown"
    outlier_frames: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))

    SPEC = {"cut_frames": (("C",), "i"), "scores": (("T",), "f"), "outlier_frames": (("F",), "i")}

    def _check_extra(self, sizes: dict[str, int]) -> None:
        if self.num_frames < 1:
            raise InputError(f"Shots.num_frames: a video needs at least one frame, got {self.num_frames}")
        if sizes["T"] != self.num_frames:
            raise InputError(f"Shots.scores: expected {self.num_frames} scores, got {sizes['T']}")
        cuts = self.cut_frames
        if cuts.size and (np.any(np.diff(cuts) <= 0) or cuts[0] <= 0 or cuts[-1] >= self.num_frames):
            raise InputError(f"Shots.cut_frames: cuts must increase strictly inside (0, {self.num_frames}), "
                             f"got {cuts.tolist()}")
        odd = self.outlier_frames
        if odd.size and (np.any(np.diff(odd) <= 0) or odd[0] < 0 or odd[-1] >= self.num_frames):
            raise InputError(f"Shots.outlier_frames: frames must increase strictly inside [0, {self.num_frames}), "
                             f"got {odd.tolist()}")
        if not self.fps > 0:
            raise InputError(f"Shots.fps: must be positive, got {self.fps}")

    @property
    def num_shots(self) -> int:
        return int(self.cut_frames.size) + 1

    @property
    def ranges(self) -> list[tuple[int, int]]:
        """``[start, end)`` frame range of every shot."""
        edges = [0, *self.cut_frames.tolist(), self.num_frames]
        return [(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:])]

    def shot_of_frame(self) -> np.ndarray:
        """``(T,)`` int: the shot index of every frame."""
        return np.searchsorted(self.cut_frames, np.arange(self.num_frames), side="right")


@dataclass(frozen=True)
class PersonTracks(_Checked):
    """People of one shot as a per-shot estimator sees them, in that shot's camera frame.

    Attributes:
        shot_index: which shot of the video.
        start_frame: video frame index of the shot's first frame.
        track_ids: ``(P,)`` int, local track ids (unique within the shot, meaningless across shots).
        global_orient: ``(P, T, 3)`` axis-angle root orientation in the camera frame.
        body_pose: ``(P, T, 23, 3)`` axis-angle joint rotations.
        betas: ``(P, 10)`` shape.
        transl: ``(P, T, 3)`` SMPL translation in the camera frame (metres, estimator's scale).
        keypoints2d: ``(P, T, J, 3)`` pixel ``u, v`` and confidence in [0, 1]; SMPL order when J = 24.
        masks: ``(P, T, H, ceil(W/8))`` uint8, bit-packed along the width (``numpy.packbits``).
        image_size: ``(H, W)`` of the video.
        K: ``(3, 3)`` intrinsics the estimator assumed for ``transl``.
        appearance: ``(P, T, D)`` appearance descriptors; meaningful where ``appearance_valid``.
        appearance_valid: ``(P, T)`` bool.
        valid: ``(P, T)`` bool, the person has a body in that frame: detected there, or carried across a
            short gap between two detections (the CPU backend's :mod:`multithumbs.perception.gap_fill`;
            keypoint confidence 0 and no mask there).
    """

    shot_index: int
    start_frame: int
    track_ids: np.ndarray
    global_orient: np.ndarray
    body_pose: np.ndarray
    betas: np.ndarray
    transl: np.ndarray
    keypoints2d: np.ndarray
    masks: np.ndarray
    image_size: tuple[int, int]
    K: np.ndarray
    appearance: np.ndarray
    appearance_valid: np.ndarray
    valid: np.ndarray

    SPEC = {
        "track_ids": (("P",), "i"),
        "global_orient": (("P", "T", 3), "f"),
        "body_pose": (("P", "T", NUM_BODY_JOINTS, 3), "f"),
        "betas": (("P", NUM_BETAS), "f"),
        "transl": (("P", "T", 3), "f"),
        "keypoints2d": (("P", "T", "J", 3), "f"),
        "masks": (("P", "T", "H", "Wb"), "u"),
        "K": ((3, 3), "f"),
        "appearance": (("P", "T", "D"), "f"),
        "appearance_valid": (("P", "T"), "b"),
        "valid": (("P", "T"), "b"),
    }

    def _check_extra(self, sizes: dict[str, int]) -> None:
        h, w = (int(s) for s in self.image_size)
        object.__setattr__(self, "image_size", (h, w))
        if sizes.get("H") != h or sizes.get("Wb") != (w + 7) // 8:
            raise InputError(f"PersonTracks.masks: expected (P, T, {h}, {(w + 7) // 8}) for image "
                             f"{h}x{w}, got {self.masks.shape}")
        if len(np.unique(self.track_ids)) != len(self.track_ids):
            raise InputError(f"PersonTracks.track_ids: ids must be unique within a shot, got "
                             f"{self.track_ids.tolist()}")

    @property
    def num_people(self) -> int:
        return int(self.track_ids.shape[0])

    @property
    def num_frames(self) -> int:
        return int(self.valid.shape[1])

    def mask(self, person: int, frame: int) -> np.ndarray:
        """``(H, W)`` bool mask of one person at one shot-local frame."""
        return unpack_mask(self.masks[person, frame], self.image_size[1])

    def people_mask(self, frames: np.ndarray | None = None) -> np.ndarray:
        """``(N, H, W)`` bool union of everyone's masks (where they are valid) at shot-local ``frames``
        (default: every frame of the shot, ``N = T``)."""
        frames = np.arange(self.num_frames) if frames is None else np.asarray(frames, int)
        packed = np.where(self.valid[:, frames, None, None], self.masks[:, frames], 0)
        union = np.bitwise_or.reduce(packed, axis=0) if len(packed) else np.zeros((len(frames), *self.masks.shape[2:]),
                                                                                    np.uint8)
        return unpack_mask(union, self.image_size[1])


def pack_mask(mask: np.ndarray) -> np.ndarray:
    """Bit-pack boolean masks ``(..., H, W)`` along the width to ``(..., H, ceil(W/8))`` uint8."""
    return np.packbits(np.asarray(mask, dtype=bool), axis=-1)


def unpack_mask(packed: np.ndarray, width: int) -> np.ndarray:
    """Inverse of :func:`pack_mask`: ``(..., H, ceil(W/8))`` uint8 to ``(..., H, W)`` bool."""
    return np.unpackbits(packed, axis=-1, count=width).astype(bool)


@dataclass(frozen=True)
class CameraTrajectory(_Checked):
    """Cameras of one shot in that shot's own tracking frame and (unknown) scale.

    Attributes:
        shot_index: which shot.
        start_frame: video frame index of the shot's first frame.
        K: ``(3, 3)`` intrinsics.
        R: ``(T, 3, 3)`` world-to-camera rotations.
        t: ``(T, 3)`` world-to-camera translations.
        points: ``(N, 3)`` sparse scene points of the tracking map in the same frame and scale, or None;
            they tie the trajectory's unknown scale to a shared space's depth.
        source: backend that produced it (``"pycolmap"``, ``"static"``, ``"simulated"``...).
    """

    shot_index: int
    start_frame: int
    K: np.ndarray
    R: np.ndarray
    t: np.ndarray
    points: np.ndarray | None = None
    source: str = "unknown"

    SPEC = {"K": ((3, 3), "f"), "R": (("T", 3, 3), "f"), "t": (("T", 3), "f"), "points": (("N", 3), "f")}

    @property
    def num_frames(self) -> int:
        return int(self.R.shape[0])


@dataclass(frozen=True)
class SharedSpace(_Checked):
    """The shared 3D space at one cut: both boundary cameras and scene points, in one frame.

    Index 0 is the last frame of the earlier shot (``t_b - 1``), index 1 the first of the next
    (``t_b``). Points carry their pixel position in each frame where they were observed; a dense
    point map of frame 0 is points observed in frame 0 only.

    Attributes:
        cut_frame: ``t_b``.
        K: ``(2, 3, 3)`` intrinsics of the two boundary frames.
        R: ``(2, 3, 3)`` world-to-camera rotations.
        t: ``(2, 3)`` world-to-camera translations.
        points: ``(N, 3)`` scene points (the space's own scale).
        pixels: ``(2, N, 2)`` pixel ``u, v`` of each point in each frame.
        observed: ``(2, N)`` bool, the point was observed in that frame (pixels meaningful).
        confidence: ``(N,)`` confidence in [0, 1].
        image_size: ``(H, W)``.
        source: backend (``"pycolmap"``, ``"vggt"``, ``"simulated"``...).
        fallback: which fallback ran, ``""`` when none did.
    """

    cut_frame: int
    K: np.ndarray
    R: np.ndarray
    t: np.ndarray
    points: np.ndarray
    pixels: np.ndarray
    observed: np.ndarray
    confidence: np.ndarray
    image_size: tuple[int, int]
    source: str = "unknown"
    fallback: str = ""

    SPEC = {
        "K": ((2, 3, 3), "f"), "R": ((2, 3, 3), "f"), "t": ((2, 3), "f"),
        "points": (("N", 3), "f"), "pixels": ((2, "N", 2), "f"), "observed": ((2, "N"), "b"),
        "confidence": (("N",), "f"),
    }


@dataclass(frozen=True)
class WorldResult(_Checked):
    """A whole video reconstructed in one world frame (also the common part of :class:`GroundTruth`).

    Attributes:
        person_ids: ``(P,)`` int global person ids.
        global_orient: ``(P, T, 3)`` axis-angle root orientation in the world frame.
        body_pose: ``(P, T, 23, 3)`` axis-angle.
        betas: ``(P, 10)``.
        transl: ``(P, T, 3)`` world SMPL translation.
        valid: ``(P, T)`` bool.
        K: ``(T, 3, 3)`` intrinsics of every frame.
        R: ``(T, 3, 3)`` world-to-camera rotation of every frame.
        t: ``(T, 3)`` world-to-camera translation of every frame.
        cut_frames: ``(C,)`` int.
        fps: frames per second.
        image_size: ``(H, W)``.
        id_map: ``(M, 3)`` int rows ``(shot, local track id, global id)``.
        keypoints2d: ``(P, T, J, 3)`` observed 2D keypoints under global ids (for GT-free metrics),
            or ``None``.
        diagnostics: named arrays (loss curves, re-ID cost matrices...).
    """

    person_ids: np.ndarray
    global_orient: np.ndarray
    body_pose: np.ndarray
    betas: np.ndarray
    transl: np.ndarray
    valid: np.ndarray
    K: np.ndarray
    R: np.ndarray
    t: np.ndarray
    cut_frames: np.ndarray
    fps: float
    image_size: tuple[int, int]
    id_map: np.ndarray
    keypoints2d: np.ndarray | None = None
    diagnostics: dict[str, np.ndarray] = field(default_factory=dict)

    SPEC = {
        "person_ids": (("P",), "i"),
        "global_orient": (("P", "T", 3), "f"),
        "body_pose": (("P", "T", NUM_BODY_JOINTS, 3), "f"),
        "betas": (("P", NUM_BETAS), "f"),
        "transl": (("P", "T", 3), "f"),
        "valid": (("P", "T"), "b"),
        "K": (("T", 3, 3), "f"),
        "R": (("T", 3, 3), "f"),
        "t": (("T", 3), "f"),
        "cut_frames": (("C",), "i"),
        "id_map": (("M", 3), "i"),
        "keypoints2d": (("P", "T", "J", 3), "f"),
    }

    def _check_extra(self, sizes: dict[str, int]) -> None:
        h, w = (int(s) for s in self.image_size)
        object.__setattr__(self, "image_size", (h, w))
        t = sizes["T"]
        cuts = self.cut_frames
        if cuts.size and (np.any(np.diff(cuts) <= 0) or cuts[0] <= 0 or cuts[-1] >= t):
            raise InputError(f"WorldResult.cut_frames: cuts must increase strictly inside (0, {t}), "
                             f"got {cuts.tolist()}")

    @property
    def num_people(self) -> int:
        return int(self.person_ids.shape[0])

    @property
    def num_frames(self) -> int:
        return int(self.R.shape[0])

    def shots(self) -> Shots:
        """The shot structure of the video (no detector scores)."""
        return Shots(self.cut_frames, self.fps, self.num_frames, np.zeros(self.num_frames), "result")


@dataclass(frozen=True)
class GroundTruth:
    """True world, people and cameras of a video: a :class:`WorldResult` plus what only truth knows.

    Attributes:
        world: the true reconstruction; its ``person_ids`` are the true identities and its
            ``keypoints2d`` the true projected SMPL joints with visibility as confidence.
        bboxes: ``(P, T, 4)`` true 2D boxes ``x0, y0, x1, y1`` of the visible body (pixels).
        visible: ``(P, T)`` bool, at least part of the person is in view (a subset of
            ``world.valid``, which says the person exists in the scene at that frame).
        camera_ids: ``(T,)`` int, which source camera each frame was taken from.
        metadata: JSON-serialisable description (scene spec, seed, dataset and sequence names).
    """

    world: WorldResult
    bboxes: np.ndarray
    visible: np.ndarray
    camera_ids: np.ndarray
    metadata: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        p, t = self.world.valid.shape
        sizes = {"P": p, "T": t}
        for name, shape, kind in (("bboxes", ("P", "T", 4), "f"), ("visible", ("P", "T"), "b"),
                                  ("camera_ids", ("T",), "i")):
            object.__setattr__(self, name, check_array("GroundTruth", name, getattr(self, name),
                                                       shape, sizes, kind))
        if self.world.keypoints2d is None or self.world.keypoints2d.shape[2] != NUM_JOINTS:
            raise InputError("GroundTruth.world.keypoints2d: ground truth needs (P, T, 24, 3) "
                             "projected SMPL joints")
