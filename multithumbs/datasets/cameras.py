"""Calibrated cameras of the real captures: intrinsics, lens distortion and metric world-to-camera pose.

Conventions (:mod:`multithumbs.conventions`): OpenCV cameras, ``x_cam = R @ x_world + t`` in metres.
Lens models are OpenCV's and are handled through OpenCV itself: ``"fisheye"`` is ``cv2.fisheye``'s
equidistant model with ``k1..k4`` (COLMAP's ``OPENCV_FISHEYE``, EgoHumans and Harmony4D's GoPros);
``"radial"`` is ``cv2.projectPoints``' radial-tangential model with any OpenCV coefficient vector
(``k1, k2, p1, p2[, k3[, k4, k5, k6]]``, EgoBody's Kinects). A camera's frames are undistorted to the
pinhole ``K`` the datasets' own tools use (``cv2.fisheye.undistortImage(img, K, D, None, K)``,
``cv2.undistort(img, K, D)``), so everything downstream is a plain pinhole camera.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import cv2
import numpy as np

from multithumbs.errors import InputError

LensModel = Literal["pinhole", "fisheye", "radial"]


@dataclass(frozen=True)
class Camera:
    """One static calibrated camera of a multi-view capture.

    Attributes:
        name: the dataset's camera name (``"cam01"``, ``"master"``...).
        K: ``(3, 3)`` intrinsics in pixels of the raw image (and of its undistorted version).
        distortion: ``(D,)`` OpenCV distortion coefficients (``(4,)`` for ``"fisheye"``, empty for
            ``"pinhole"``).
        model: lens model, see the module docstring.
        R: ``(3, 3)`` metric world-to-camera rotation.
        t: ``(3,)`` metric world-to-camera translation (metres).
        image_size: ``(H, W)`` of the raw frames.
    """

    name: str
    K: np.ndarray
    distortion: np.ndarray
    model: LensModel
    R: np.ndarray
    t: np.ndarray
    image_size: tuple[int, int]

    def __post_init__(self) -> None:
        for field, shape in (("K", (3, 3)), ("R", (3, 3)), ("t", (3,))):
            value = np.asarray(getattr(self, field), dtype=np.float64)
            if value.shape != shape or not np.all(np.isfinite(value)):
                raise InputError(f"camera {self.name}: {field} must be a finite {shape} array, got shape {value.shape}")
            object.__setattr__(self, field, value)
        dist = np.asarray(self.distortion, dtype=np.float64).reshape(-1)
        if self.model == "fisheye" and dist.size != 4:
            raise InputError(f"camera {self.name}: a fisheye lens has 4 coefficients k1..k4, got {dist.size}")
        if self.model == "radial" and dist.size not in (4, 5, 8, 12, 14):
            raise InputError(f"camera {self.name}: OpenCV takes 4, 5, 8, 12 or 14 distortion coefficients, "
                             f"got {dist.size}")
        if self.model not in ("pinhole", "fisheye", "radial"):
            raise InputError(f"camera {self.name}: unknown lens model {self.model!r}")
        if not np.allclose(self.R @ self.R.T, np.eye(3), atol=1e-6) or np.linalg.det(self.R) < 0:
            raise InputError(f"camera {self.name}: R is not a rotation (scaled or reflected extrinsics?)")
        object.__setattr__(self, "distortion", dist)
        object.__setattr__(self, "image_size", tuple(int(s) for s in self.image_size))

    @property
    def centre(self) -> np.ndarray:
        """``(3,)`` camera centre ``C = -R^T t`` in the world (metres)."""
        return -self.R.T @ self.t

    def project(self, points: np.ndarray) -> np.ndarray:
        """World points ``(..., 3)`` to RAW (distorted) pixel coordinates ``(..., 2)``, through OpenCV.

        Points behind the camera get coordinates too (OpenCV's); mask them with :meth:`depth`.
        """
        points = np.asarray(points, dtype=np.float64)
        flat = points.reshape(-1, 1, 3)
        if flat.shape[0] == 0:
            return np.zeros((*points.shape[:-1], 2))
        rvec, _ = cv2.Rodrigues(self.R)
        if self.model == "fisheye":
            uv, _ = cv2.fisheye.projectPoints(flat, rvec, self.t.reshape(3, 1), self.K, self.distortion)
        else:
            uv, _ = cv2.projectPoints(flat, rvec, self.t, self.K, self.distortion if self.model == "radial" else None)
        return uv.reshape(*points.shape[:-1], 2)

    def project_undistorted(self, points: np.ndarray) -> np.ndarray:
        """World points ``(..., 3)`` to pixels ``(..., 2)`` of the UNDISTORTED frame (pinhole ``K``)."""
        cam = self.to_camera(points)
        z = np.maximum(cam[..., 2:3], 1e-9)
        return ((cam / z) @ self.K.T)[..., :2]

    def to_camera(self, points: np.ndarray) -> np.ndarray:
        """World points ``(..., 3)`` in camera coordinates ``(..., 3)``."""
        return np.asarray(points, dtype=np.float64) @ self.R.T + self.t

    def depth(self, points: np.ndarray) -> np.ndarray:
        """``(...)`` z-depth of world points ``(..., 3)`` (metres, negative behind the camera)."""
        return self.to_camera(points)[..., 2]

    def undistort_points(self, pixels: np.ndarray) -> np.ndarray:
        """Raw pixel coordinates ``(..., 2)`` to the undistorted frame's pixels ``(..., 2)`` (same ``K``)."""
        pixels = np.asarray(pixels, dtype=np.float64)
        flat = pixels.reshape(-1, 1, 2)
        if self.model == "pinhole" or flat.shape[0] == 0:
            return pixels.copy()
        if self.model == "fisheye":
            out = cv2.fisheye.undistortPoints(flat, self.K, self.distortion, P=self.K)
        else:
            out = cv2.undistortPoints(flat, self.K, self.distortion, P=self.K)
        return out.reshape(pixels.shape)

    def undistort_image(self, image: np.ndarray) -> np.ndarray:
        """The pinhole image with intrinsics ``K`` seen by this camera (``(H, W, C)`` in, same shape out)."""
        if self.model == "pinhole":
            return image
        if self.model == "fisheye":
            return cv2.fisheye.undistortImage(image, self.K, self.distortion, Knew=self.K,
                                              new_size=(image.shape[1], image.shape[0]))
        return cv2.undistort(image, self.K, self.distortion)


def metric_extrinsics(world_to_camera: np.ndarray, source: str = "extrinsics") -> tuple[np.ndarray, np.ndarray, float]:
    """Split a world-to-camera ``(3, 4)`` or ``(4, 4)`` matrix that may carry a scale into metric ``R, t``.

    ``E = [R|t]_colmap @ T_align`` with a similarity ``T_align`` has ``E[:3, :3] = s R``; the metric
    camera is ``R = E[:3, :3] / s``, ``t = E[:3, 3] / s`` with ``s = cbrt(det(E[:3, :3]))`` (DATASETS.md §0).
    Projection to pixels is the same either way.

    Returns:
        ``R (3, 3)``, ``t (3,)`` and the scale ``s`` that was removed.
    """
    E = np.asarray(world_to_camera, dtype=np.float64)
    if E.shape not in ((3, 4), (4, 4)) or not np.all(np.isfinite(E)):
        raise InputError(f"{source}: expected a finite 3x4 or 4x4 world-to-camera matrix, got shape {E.shape}")
    det = np.linalg.det(E[:3, :3])
    if not det > 1e-12:
        raise InputError(f"{source}: the rotation part has determinant {det:.3g} (not a proper similarity)")
    scale = float(np.cbrt(det))
    R = E[:3, :3] / scale
    # Re-orthonormalise away round-off (SVD polar factor) so the camera passes the rotation check.
    u, _, vt = np.linalg.svd(R)
    R_clean = u @ vt
    if np.abs(R_clean - R).max() > 1e-4:
        raise InputError(f"{source}: the rotation part is not a scaled rotation (shear or anisotropic scale)")
    return R_clean, E[:3, 3] / scale, scale


__all__ = ["Camera", "LensModel", "metric_extrinsics"]
