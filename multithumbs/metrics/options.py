"""The evaluation's open choices (docs/METRICS.md "Options"), with the field's defaults; reports echo them."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from multithumbs.errors import InputError
from multithumbs.metrics.pose import WORLD_CHUNK


@dataclass(frozen=True)
class EvaluationOptions:
    """Every open choice of the evaluation, with docs/METRICS.md's defaults; the report echoes them.

    Attributes:
        chunk: valid frames per re-alignment chunk of the headline ``w_mpjpe`` / ``wa_mpjpe`` (100 as
            WHAM/GVHMR's W-MPJPE100); None for one chunk per track. ``*_track`` are always reported.
        root_align: ``mpjpe`` and ``mpvpe`` subtract the pelvis (``*_world`` are always unaligned).
        include_cuts: ``accel_world`` and Jitter count windows that span a cut.
        id_association: ``"box_iou"`` (2D boxes) or ``"root_distance"`` (3D roots, when boxes are
            unavailable) for the per-frame IDs association.
        truth_boxes: the true boxes the IoU association uses: ``"mesh"``, the true mesh projected by the
            true camera and clipped to the image, which is amodal like the predicted boxes (and like
            MOTChallenge's full-body boxes); or ``"given"``, ``GroundTruth.bboxes`` as the dataset has them
            (in the synthetic suite the box of the visible part, which shrinks under occlusion while the
            predicted box does not, and makes switches between overlapping people that never happened).
        min_iou: IoU a box pair needs to be associated.
        max_root_distance: metres a root pair may be apart to be associated.
        pck_alpha: PCK* threshold as a fraction of the keypoint box size (the ``pck`` key).
        min_keypoint_confidence: PCK* uses keypoints above this confidence.
        contact_speed: FS with truth: metres per frame under which a true foot point is in contact.
        contact_height: FS without truth: metres above the ground that count as contact.
        ground_percentile: FS without truth: percentile of a person's foot heights taken as the ground.
        up: FS without truth: the reconstruction's up direction; None estimates it from the bodies.
    """

    chunk: int | None = WORLD_CHUNK
    root_align: bool = True
    include_cuts: bool = True
    id_association: Literal["box_iou", "root_distance"] = "box_iou"
    truth_boxes: Literal["mesh", "given"] = "mesh"
    min_iou: float = 0.5
    max_root_distance: float = 0.5
    pck_alpha: float = 0.1
    min_keypoint_confidence: float = 0.5
    contact_speed: float = 0.01
    contact_height: float = 0.05
    ground_percentile: float = 5.0
    up: tuple[float, float, float] | None = None

    def __post_init__(self) -> None:
        if self.chunk is not None and int(self.chunk) < 1:
            raise InputError(f"chunk: must be a positive number of frames or None, got {self.chunk}")
        if self.id_association not in ("box_iou", "root_distance"):
            raise InputError(f"id_association: expected 'box_iou' or 'root_distance', got {self.id_association!r}")
        if self.truth_boxes not in ("mesh", "given"):
            raise InputError(f"truth_boxes: expected 'mesh' or 'given', got {self.truth_boxes!r}")
        for name in ("min_iou", "max_root_distance", "pck_alpha", "contact_speed", "contact_height"):
            if not getattr(self, name) > 0:
                raise InputError(f"{name}: must be positive, got {getattr(self, name)}")
        if not 0 <= self.ground_percentile <= 100:
            raise InputError(f"ground_percentile: must be in [0, 100], got {self.ground_percentile}")
        if self.up is not None:
            up = tuple(float(u) for u in self.up)
            if len(up) != 3 or not np.linalg.norm(up) > 0:
                raise InputError(f"up: expected a non-zero 3-vector, got {self.up}")
            object.__setattr__(self, "up", up)

    @staticmethod
    def from_kwargs(options: dict[str, Any]) -> "EvaluationOptions":
        """Build from keyword options, naming any unknown one."""
        known = EvaluationOptions.__dataclass_fields__
        unknown = sorted(set(options) - set(known))
        if unknown:
            raise InputError(f"evaluation options: unknown {unknown}; known are {sorted(known)}")
        return EvaluationOptions(**options)
