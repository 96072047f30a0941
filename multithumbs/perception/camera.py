"""The camera models of HMR2 / 4DHumans / PHALP, converted to this project's pinhole cameras.

HMR2 regresses a weak-perspective camera ``(s, tx, ty)`` on a square crop of side ``b`` pixels around
the person (``b`` = the box's longer side after HMR2's aspect expansion). With focal length ``F`` for a
crop of ``R`` pixels (``F = 5000``, ``R = 256``), the crop camera is the translation
``(tx, ty, 2F / (R s))``. For the full image, 4DHumans scales the focal length to the image,
``f = F / R * max(H, W)``, keeps the principal point at the image centre and moves the translation so the
person projects where the box is (``hmr2.utils.renderer.cam_crop_to_full``)::

    tz = 2 f / (b s),   tx' = tx + 2 (cx - W/2) / (b s),   ty' = ty + 2 (cy - H/2) / (b s)

with ``(cx, cy)`` the box centre. PHALP does the same on the frame zero-padded to a ``max(H, W)`` square
and resized to ``R``: its ``camera`` field is that translation for focal ``F`` on the ``R``-pixel square,
which is the same 3D translation for focal ``F / R * max(H, W)`` on the padded full-resolution square. So
the translation is kept as is and the intrinsics that go with it are :func:`hmr2_intrinsics`.

Pixel centres: HMR2 and PHALP measure pixels continuously (the image spans ``[0, W]``); this project puts
pixel centres at integers (:mod:`multithumbs.conventions`), so their coordinates are shifted by -0.5.
"""

from __future__ import annotations

import numpy as np

HMR2_FOCAL_LENGTH = 5000.0
"""HMR2's focal length for its crop (``EXTRA.FOCAL_LENGTH``)."""
HMR2_CROP_SIZE = 256
"""HMR2's crop size in pixels (``MODEL.IMAGE_SIZE``) and PHALP's ``render.res``."""


def hmr2_focal_length(image_size: tuple[int, int], focal_length: float = HMR2_FOCAL_LENGTH,
                      crop_size: int = HMR2_CROP_SIZE) -> float:
    """Focal length in pixels that 4DHumans assumes for an ``(H, W)`` image: ``F / R * max(H, W)``."""
    return float(focal_length) / float(crop_size) * float(max(image_size))


def hmr2_intrinsics(image_size: tuple[int, int], focal_length: float = HMR2_FOCAL_LENGTH,
                    crop_size: int = HMR2_CROP_SIZE, padded_square: bool = True) -> np.ndarray:
    """``(3, 3)`` intrinsics of HMR2's full-image camera (and of PHALP's ``camera`` translations).

    With ``padded_square`` (PHALP) the principal point is the centre of the frame zero-padded to a square
    as PHALP pads it (``left = (S - W) // 2``, ``top = (S - H) // 2``); without it (``cam_crop_to_full``
    in 4DHumans' demo) it is ``(W/2, H/2)``. Both are shifted to integer pixel centres.
    """
    h, w = (int(s) for s in image_size)
    f = hmr2_focal_length((h, w), focal_length, crop_size)
    if padded_square:
        side = max(h, w)
        cx, cy = side / 2.0 - (side - w) // 2, side / 2.0 - (side - h) // 2
    else:
        cx, cy = w / 2.0, h / 2.0
    return np.array([[f, 0.0, cx - 0.5], [0.0, f, cy - 0.5], [0.0, 0.0, 1.0]])


def cam_crop_to_full(cam_crop: np.ndarray, box_center: np.ndarray, box_size: np.ndarray,
                     image_size: tuple[int, int], focal_length: float) -> np.ndarray:
    """HMR2's weak-perspective crop camera to a full-image camera translation (``cam_crop_to_full``).

    Args:
        cam_crop: ``(..., 3)`` ``(s, tx, ty)`` as HMR2's ``pred_cam``.
        box_center: ``(..., 2)`` crop centre in HMR2's continuous pixel coordinates.
        box_size: ``(...)`` crop side in pixels.
        image_size: ``(H, W)``.
        focal_length: full-image focal length in pixels (:func:`hmr2_focal_length`).
    Returns:
        ``(..., 3)`` translation of the SMPL body in the camera frame (metres), for the intrinsics
        :func:`hmr2_intrinsics` when ``focal_length`` is the default scaling.
    """
    cam = np.asarray(cam_crop, dtype=np.float64)
    centre = np.asarray(box_center, dtype=np.float64)
    b = np.asarray(box_size, dtype=np.float64)
    h, w = image_size
    bs = b * cam[..., 0] + 1e-9
    tz = 2.0 * focal_length / bs
    tx = 2.0 * (centre[..., 0] - w / 2.0) / bs + cam[..., 1]
    ty = 2.0 * (centre[..., 1] - h / 2.0) / bs + cam[..., 2]
    return np.stack([tx, ty, tz], axis=-1)


def phalp_joints_to_pixels(joints: np.ndarray, image_size: tuple[int, int]) -> np.ndarray:
    """PHALP's ``2d_joints`` ``(..., 2N)`` (normalised to the padded square) to pixels ``(..., N, 2)``."""
    h, w = image_size
    side = max(h, w)
    left, top = (side - w) // 2, (side - h) // 2
    xy = np.asarray(joints, dtype=np.float64).reshape(*np.shape(joints)[:-1], -1, 2) * side
    return xy - np.array([left + 0.5, top + 0.5])


def pixels_to_phalp_joints(pixels: np.ndarray, image_size: tuple[int, int]) -> np.ndarray:
    """Inverse of :func:`phalp_joints_to_pixels`: ``(..., N, 2)`` pixels to ``(..., 2N)``."""
    h, w = image_size
    side = max(h, w)
    left, top = (side - w) // 2, (side - h) // 2
    xy = (np.asarray(pixels, dtype=np.float64) + np.array([left + 0.5, top + 0.5])) / side
    return xy.reshape(*xy.shape[:-2], -1)
