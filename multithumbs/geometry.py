"""Rotations, cameras, projection and similarity alignment. Conventions: :mod:`multithumbs.conventions`.

Functions take torch tensors with any leading batch dimensions ``...``; those marked
``numpy in, numpy out`` also accept numpy arrays and return them (computed in float64).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Callable, TypeVar

import numpy as np
import roma
import torch

F = TypeVar("F", bound=Callable)


def numpy_compatible(fn: F) -> F:
    """Let a torch function take numpy arrays: convert them to float64 tensors and the results back."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        is_numpy = any(isinstance(a, np.ndarray) for a in (*args, *kwargs.values()))
        if not is_numpy:
            return fn(*args, **kwargs)
        conv = lambda a: torch.from_numpy(np.array(a, dtype=np.float64)) if isinstance(a, np.ndarray) else a
        out = fn(*(conv(a) for a in args), **{k: conv(v) for k, v in kwargs.items()})
        back = lambda o: o.detach().cpu().numpy() if isinstance(o, torch.Tensor) else o
        if isinstance(out, tuple):
            return type(out)(*(back(o) for o in out)) if hasattr(out, "_fields") else tuple(back(o) for o in out)
        return back(out)

    return wrapper  # type: ignore[return-value]


@numpy_compatible
def axis_angle_to_matrix(rotvec: torch.Tensor) -> torch.Tensor:
    """``(..., 3)`` axis-angle to ``(..., 3, 3)`` rotation matrices. numpy in, numpy out."""
    return roma.rotvec_to_rotmat(rotvec)


@numpy_compatible
def matrix_to_axis_angle(rotmat: torch.Tensor) -> torch.Tensor:
    """``(..., 3, 3)`` rotation matrices to ``(..., 3)`` axis-angle (angle in [0, pi]). numpy in, numpy out."""
    return roma.rotmat_to_rotvec(rotmat)


def rotation_6d_to_matrix(d6: torch.Tensor) -> torch.Tensor:
    """``(..., 6)`` continuous 6D representation (first two columns) to ``(..., 3, 3)`` (Zhou et al.)."""
    return roma.special_gramschmidt(d6.reshape(*d6.shape[:-1], 3, 2))


def matrix_to_rotation_6d(rotmat: torch.Tensor) -> torch.Tensor:
    """``(..., 3, 3)`` to the ``(..., 6)`` representation read by :func:`rotation_6d_to_matrix`."""
    return rotmat[..., :, :2].reshape(*rotmat.shape[:-2], 6)


@numpy_compatible
def rotation_angle(rotmat_a: torch.Tensor, rotmat_b: torch.Tensor) -> torch.Tensor:
    """``(...)`` geodesic angle in radians between rotations ``(..., 3, 3)``. numpy in, numpy out."""
    return roma.rotmat_geodesic_distance(rotmat_a, rotmat_b)


@numpy_compatible
def camera_centre(R: torch.Tensor, t: torch.Tensor) -> torch.Tensor:
    """Camera centre ``C = -R^T t`` from world-to-camera ``R (..., 3, 3)``, ``t (..., 3)``. numpy in, numpy out."""
    return -(R.transpose(-1, -2) @ t.unsqueeze(-1)).squeeze(-1)


@numpy_compatible
def world_to_camera(points: torch.Tensor, R: torch.Tensor, t: torch.Tensor) -> torch.Tensor:
    """``x_cam = R x + t`` for points ``(..., N, 3)`` with ``R (..., 3, 3)``, ``t (..., 3)``. numpy in, numpy out."""
    return points @ R.transpose(-1, -2) + t.unsqueeze(-2)


@numpy_compatible
def project(points_cam: torch.Tensor, K: torch.Tensor, eps: float = 1e-6) -> torch.Tensor:
    """Pinhole projection of camera-frame points ``(..., N, 3)`` with ``K (..., 3, 3)`` to pixels ``(..., N, 2)``.

    Depths are clamped to ``eps`` so points behind the camera stay finite (callers mask them by
    depth). numpy in, numpy out.
    """
    z = points_cam[..., 2:3].clamp(min=eps)
    uv1 = (points_cam / z) @ K.transpose(-1, -2)
    return uv1[..., :2]


@numpy_compatible
def project_points(points: torch.Tensor, K: torch.Tensor, R: torch.Tensor, t: torch.Tensor) -> torch.Tensor:
    """World points ``(..., N, 3)`` to pixels ``(..., N, 2)`` through camera ``K, R, t``. numpy in, numpy out."""
    return project(world_to_camera(points, R, t), K)


@numpy_compatible
def unproject(pixels: torch.Tensor, depth: torch.Tensor, K: torch.Tensor) -> torch.Tensor:
    """Pixels ``(..., N, 2)`` with z-depth ``(..., N)`` to camera-frame points ``(..., N, 3)``. numpy in, numpy out."""
    ones = torch.ones_like(pixels[..., :1])
    rays = torch.cat([pixels, ones], dim=-1) @ torch.linalg.inv(K).transpose(-1, -2)
    return rays * depth.unsqueeze(-1)


@numpy_compatible
def reexpress_for_intrinsics(points_cam: torch.Tensor, K_from: torch.Tensor, K_to: torch.Tensor) -> torch.Tensor:
    """Camera-frame points ``(..., N, 3)`` given for intrinsics ``K_from (..., 3, 3)``, re-expressed for ``K_to``.

    Each point keeps its pixel and its depth scales by the focal-length ratio ``sqrt(fx fy)`` of ``K_to`` over
    ``K_from``, so an object keeps its projected size: what a monocular estimator would have reported had it
    known the real camera. Estimators such as HMR2 / 4DHumans assume a focal length of their own
    (:mod:`multithumbs.perception.camera`); their translations are converted with this before they meet the
    scene's cameras. The identity when the intrinsics are equal. numpy in, numpy out.
    """
    ratio = torch.sqrt(K_to[..., 0, 0] * K_to[..., 1, 1] / (K_from[..., 0, 0] * K_from[..., 1, 1]))
    return unproject(project(points_cam, K_from), points_cam[..., 2] * ratio[..., None], K_to)


def intrinsics(fx: float, fy: float, cx: float, cy: float) -> np.ndarray:
    """``(3, 3)`` pinhole intrinsics."""
    return np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])


def intrinsics_from_fov(width: int, height: int, horizontal_fov_deg: float) -> np.ndarray:
    """``(3, 3)`` intrinsics of a centred pinhole camera with square pixels and the given horizontal FOV."""
    f = 0.5 * width / np.tan(np.deg2rad(horizontal_fov_deg) / 2)
    return intrinsics(f, f, (width - 1) / 2, (height - 1) / 2)


def look_at(eye: np.ndarray, target: np.ndarray, up: np.ndarray = np.array([0.0, 0.0, 1.0])
            ) -> tuple[np.ndarray, np.ndarray]:
    """World-to-camera ``R (..., 3, 3)``, ``t (..., 3)`` of OpenCV cameras at ``eye (..., 3)`` looking at ``target``.

    The image's down axis is the projection of ``-up``.
    """
    eye, target = np.asarray(eye, float), np.asarray(target, float)
    z = target - eye
    z = z / np.linalg.norm(z, axis=-1, keepdims=True)
    x = np.cross(z, np.broadcast_to(up, z.shape))
    x = x / np.linalg.norm(x, axis=-1, keepdims=True)
    y = np.cross(z, x)
    R = np.stack([x, y, z], axis=-2)
    t = -(R @ eye[..., None])[..., 0]
    return R, t


@dataclass(frozen=True)
class Similarity:
    """A similarity transform ``y = s R x + t`` (Sim(3); SE(3) when ``s = 1``), batch-agnostic.

    Attributes:
        scale: ``(...)`` positive scale.
        rotation: ``(..., 3, 3)``.
        translation: ``(..., 3)``.
    """

    scale: torch.Tensor
    rotation: torch.Tensor
    translation: torch.Tensor

    def apply(self, points: torch.Tensor) -> torch.Tensor:
        """Transform points ``(..., N, 3)``."""
        return self.scale[..., None, None] * points @ self.rotation.transpose(-1, -2) + self.translation[..., None, :]

    def inverse(self) -> "Similarity":
        r_inv = self.rotation.transpose(-1, -2)
        s_inv = 1.0 / self.scale
        return Similarity(s_inv, r_inv, -s_inv[..., None] * (r_inv @ self.translation[..., None])[..., 0])

    def compose(self, other: "Similarity") -> "Similarity":
        """``self ∘ other``: apply ``other`` first."""
        return Similarity(self.scale * other.scale, self.rotation @ other.rotation,
                          self.apply(other.translation[..., None, :])[..., 0, :])

    def numpy(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(s, R, t)`` as numpy arrays."""
        return tuple(x.detach().cpu().numpy() for x in (self.scale, self.rotation, self.translation))  # type: ignore[return-value]

    @staticmethod
    def from_numpy(scale, rotation, translation) -> "Similarity":
        as_t = lambda a: torch.as_tensor(np.asarray(a, dtype=np.float64))
        return Similarity(as_t(scale), as_t(rotation), as_t(translation))


def umeyama(source: torch.Tensor | np.ndarray, target: torch.Tensor | np.ndarray,
            weights: torch.Tensor | np.ndarray | None = None, with_scale: bool = True) -> Similarity:
    """Least-squares similarity (Umeyama 1991) mapping ``source (..., N, 3)`` onto ``target (..., N, 3)``.

    Minimises ``sum_i w_i ||s R x_i + t - y_i||^2`` with the reflection fix, ``s = tr(DS) / var(x)``;
    ``with_scale=False`` gives SE(3) (Kabsch). Numpy inputs are computed in float64.
    """
    to_t = lambda a: torch.from_numpy(np.array(a, dtype=np.float64)) if isinstance(a, np.ndarray) else a
    x, y, w = to_t(source), to_t(target), to_t(weights)
    out = roma.rigid_points_registration(x, y, weights=w, compute_scaling=with_scale)
    if with_scale:
        R, t, s = out
    else:
        (R, t), s = out, torch.ones(x.shape[:-2], dtype=x.dtype)
    return Similarity(s, R, t)


def transform_cameras(sim: Similarity, R: torch.Tensor, t: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Re-express world-to-camera ``R (..., 3, 3)``, ``t (..., 3)`` after the world moves by ``x' = s Q x + u``.

    A camera seeing ``x`` as ``R x + t`` sees the same point ``x'`` at ``(R Q^T x' + s t - R Q^T u) / s``;
    the returned extrinsics keep metric camera coordinates scaled by ``s`` (``R' = R Q^T``,
    ``t' = s t - R' u``), so camera centres transform as points.
    """
    R_new = R @ sim.rotation.transpose(-1, -2)
    t_new = sim.scale[..., None] * t - (R_new @ sim.translation[..., None])[..., 0]
    return R_new, t_new


def vertex_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Area-weighted unit vertex normals of meshes ``(..., V, 3)`` with faces ``(F, 3)`` (counter-clockwise out)."""
    flat = np.asarray(vertices, dtype=np.float64).reshape(-1, *np.shape(vertices)[-2:])
    v_count = flat.shape[1]
    normals = np.empty_like(flat)
    for mesh, out in zip(flat, normals):
        tri = mesh[faces]
        face_normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])  # length = 2 * area
        for c in range(3):
            out[:, c] = sum(np.bincount(faces[:, k], weights=face_normals[:, c], minlength=v_count) for k in range(3))
    normals /= np.maximum(np.linalg.norm(normals, axis=-1, keepdims=True), 1e-12)
    return normals.reshape(np.shape(vertices))
