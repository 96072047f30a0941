"""CPU renderer for the synthetic benchmark: RGB, exact z-depth and instance masks of people in a room.

The room (:mod:`multithumbs.synth.room`) is ray cast: every pixel's ray against the six room planes
from inside and the slabs of the boxes, nearest positive hit, texture sampled from the room's atlas in
one ``cv2.remap``. People are triangle meshes rasterised by a vectorised numpy z-buffer (no Python loop
over triangles) that is z-tested against the room's depth. Both get Lambertian + ambient shading from a
fixed light. Cameras follow :mod:`multithumbs.conventions`: OpenCV pinhole, ``x_cam = R x + t``, pixel
``(u, v)`` is the ray through ``K^-1 [u, v, 1]``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import cv2
import numpy as np

from multithumbs.errors import InputError
from multithumbs.geometry import vertex_normals
from multithumbs.synth.room import NUM_ROOM_SURFACES, TEXEL_SIZE, Box, Room, room_surfaces
from multithumbs.synth.textures import texture_atlas
from multithumbs.types import check_array

NEAR_PLANE = 0.05
"""Triangles with a vertex closer than this to the camera plane (metres) are dropped."""

ROOM_PLANE_IDS = np.array([[2, 3], [4, 5], [0, 1]])
"""Surface id of the room plane on axis ``a`` (0 x, 1 y, 2 z) at its low (0) or high (1) side."""


@dataclass(frozen=True)
class MeshInstance:
    """A coloured triangle mesh in the world frame (a person, or any object to draw).

    Attributes:
        vertices: ``(V, 3)`` world-frame positions, metres.
        faces: ``(F, 3)`` int vertex indices (either winding: shading is two-sided).
        vertex_colors: ``(V, 3)`` float RGB in [0, 1].
    """

    vertices: np.ndarray
    faces: np.ndarray
    vertex_colors: np.ndarray

    def __post_init__(self) -> None:
        sizes: dict[str, int] = {}
        for name, shape, kind in (("vertices", ("V", 3), "f"), ("faces", ("F", 3), "i"),
                                  ("vertex_colors", ("V", 3), "f")):
            object.__setattr__(self, name, check_array("MeshInstance", name, getattr(self, name), shape, sizes, kind))
        if not np.all(np.isfinite(self.vertices)):
            raise InputError("MeshInstance.vertices: contains non-finite values")
        if self.faces.size and (self.faces.min() < 0 or self.faces.max() >= len(self.vertices)):
            raise InputError(f"MeshInstance.faces: indices must lie in [0, {len(self.vertices)}), "
                             f"got [{self.faces.min()}, {self.faces.max()}]")
        if self.vertex_colors.size and not (self.vertex_colors.min() >= 0 and self.vertex_colors.max() <= 1):
            raise InputError("MeshInstance.vertex_colors: values must lie in [0, 1]")


@dataclass(frozen=True)
class Render:
    """One rendered view.

    Attributes:
        rgb: ``(H, W, 3)`` uint8 RGB.
        depth: ``(H, W)`` float32 z-depth in metres along the camera's +z axis, ``inf`` where nothing.
        instance: ``(H, W)`` int16 index into the rendered meshes, -1 for the room.
    """

    rgb: np.ndarray
    depth: np.ndarray
    instance: np.ndarray


@dataclass(frozen=True)
class Lighting:
    """Fixed shading of the scene: ``colour * (ambient + diffuse * max(0, n . l))``.

    Attributes:
        direction: ``(3,)`` world direction towards the (distant) light; normalised on use. Tilted so
            that the four walls and the box faces each get a different brightness.
        ambient: brightness of faces turned away from the light.
        diffuse: added brightness of a face looking straight at the light.
    """

    direction: tuple[float, float, float] = (0.35, 0.6, 1.0)
    ambient: float = 0.5
    diffuse: float = 0.55

    def shading(self, normals: np.ndarray) -> np.ndarray:
        """``(...)`` brightness factor for unit normals ``(..., 3)``."""
        light = np.asarray(self.direction, float)
        light = light / np.linalg.norm(light)
        return self.ambient + self.diffuse * np.clip(normals @ light, 0.0, None)


@dataclass(frozen=True)
class Fragments:
    """Visible triangle per pixel after z-buffering.

    Attributes:
        face: ``(H, W)`` int index of the visible face, -1 where no face is in front of the depth limit.
        barycentric: ``(H, W, 3)`` perspective-correct barycentric coordinates of the pixel centre in
            that face (0 where none).
        depth: ``(H, W)`` z-depth of the visible face, the depth limit where none.
    """

    face: np.ndarray
    barycentric: np.ndarray
    depth: np.ndarray


def _check_camera(K, R, t, image_size) -> tuple[np.ndarray, np.ndarray, np.ndarray, int, int]:
    K, R, t = (np.asarray(a, dtype=float) for a in (K, R, t))
    for name, arr, shape in (("K", K, (3, 3)), ("R", R, (3, 3)), ("t", t, (3,))):
        if arr.shape != shape or not np.all(np.isfinite(arr)):
            raise InputError(f"render: camera {name} must be a finite array of shape {shape}, got {arr.shape}")
    if not np.allclose(R @ R.T, np.eye(3), atol=1e-6) or np.linalg.det(R) <= 0:
        raise InputError("render: camera R must be a rotation matrix")
    if len(image_size) != 2 or min(int(s) for s in image_size) < 1:
        raise InputError(f"render: image_size must be (height, width) > 0, got {image_size!r}")
    return K, R, t, int(image_size[0]), int(image_size[1])


def camera_rays(K: np.ndarray, R: np.ndarray, t: np.ndarray, image_size: tuple[int, int]
                ) -> tuple[np.ndarray, np.ndarray]:
    """World-frame rays through every pixel centre.

    Returns:
        origin: ``(3,)`` camera centre.
        directions: ``(H, W, 3)`` ray directions ``R^T K^-1 [u, v, 1]``, scaled so that their camera-z
            component is 1: a ray parameter is then the z-depth.
    """
    h, w = image_size
    to_world = R.T @ np.linalg.inv(K)
    u, v = np.arange(w, dtype=float), np.arange(h, dtype=float)[:, None]
    # Built axis-first so that each component is a contiguous (H, W) array: the casters work per axis.
    components = np.stack([m[0] * u + m[1] * v + m[2] for m in to_world])
    return -R.T @ t, np.moveaxis(components, 0, -1)


def ray_room_exit(origin: np.ndarray, directions: np.ndarray, lo: np.ndarray, hi: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Where rays from ``origin`` inside the box ``[lo, hi]`` leave it.

    Args:
        origin: ``(3,)`` inside the box.
        directions: ``(..., 3)`` ray directions (not necessarily unit).
        lo, hi: ``(3,)`` corners.
    Returns:
        param: ``(...)`` ray parameter of the exit point.
        plane: ``(...)`` int, room plane id (see :data:`ROOM_PLANE_IDS`).
    """
    best = np.full(directions.shape[:-1], np.inf)
    plane = np.zeros(directions.shape[:-1], np.int64)
    for axis in range(3):
        d = directions[..., axis]
        ahead = d > 0
        with np.errstate(divide="ignore"):
            # Distance to the plane ahead on this axis; rays parallel to it get +inf.
            param = np.where(ahead, hi[axis] - origin[axis], origin[axis] - lo[axis]) / np.abs(d)
        closer = param < best
        best = np.where(closer, param, best)
        plane = np.where(closer, ROOM_PLANE_IDS[axis, 0] + ahead, plane)
    return best, plane


def ray_box_entry(origin: np.ndarray, directions: np.ndarray, lo: np.ndarray, hi: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Where rays from ``origin`` outside the box ``[lo, hi]`` enter it (slab method).

    Args:
        origin: ``(3,)``.
        directions: ``(..., 3)``.
        lo, hi: ``(3,)`` corners.
    Returns:
        param: ``(...)`` ray parameter of the entry point, ``inf`` for rays that miss (or start inside).
        face: ``(...)`` int ``2 a + s``: the face on axis ``a`` at the box's low (0) or high (1) side.
    """
    t_in = np.full(directions.shape[:-1], -np.inf)
    t_out = np.full(directions.shape[:-1], np.inf)
    face = np.zeros(directions.shape[:-1], np.int64)
    with np.errstate(divide="ignore", invalid="ignore"):
        for axis in range(3):
            d = directions[..., axis]
            inv = 1.0 / d  # +-inf for parallel rays: the slab is then everything or nothing
            t_lo, t_hi = (lo[axis] - origin[axis]) * inv, (hi[axis] - origin[axis]) * inv
            near = np.minimum(t_lo, t_hi)
            later = near > t_in
            t_in = np.where(later, near, t_in)
            face = np.where(later, 2 * axis + (d < 0), face)  # going towards -axis: enter the high face
            t_out = np.minimum(t_out, np.maximum(t_lo, t_hi))
    hit = (t_in <= t_out) & (t_in > 0)
    return np.where(hit, t_in, np.inf), face


def _box_window(box: Box, K: np.ndarray, R: np.ndarray, t: np.ndarray, h: int, w: int
                ) -> tuple[slice, slice] | None:
    """Pixel rows and columns that can see ``box`` (its projected corners' bounding box), None if none."""
    corners = np.stack(np.meshgrid(*zip(box.lo, box.hi), indexing="ij"), axis=-1).reshape(8, 3)
    cam = corners @ R.T + t
    if np.all(cam[:, 2] <= 0):
        return None  # wholly behind the camera: no forward ray reaches it
    if np.any(cam[:, 2] <= 1e-6):
        return slice(0, h), slice(0, w)  # straddles the camera plane: the projection is unbounded
    uv = (cam / cam[:, 2:3]) @ K.T
    u0, v0 = np.floor(uv[:, :2].min(axis=0)).astype(int) - 1
    u1, v1 = np.ceil(uv[:, :2].max(axis=0)).astype(int) + 2
    rows, cols = slice(max(v0, 0), min(v1, h)), slice(max(u0, 0), min(u1, w))
    if rows.start >= rows.stop or cols.start >= cols.stop:
        return None
    return rows, cols


def cast_room(room: Room, K: np.ndarray, R: np.ndarray, t: np.ndarray, image_size: tuple[int, int]
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Ray cast the room from a camera inside it.

    Returns:
        depth: ``(H, W)`` float64 z-depth of the nearest room surface.
        surface: ``(H, W)`` int surface id hit (:func:`multithumbs.synth.room.room_surfaces`).
        points: ``(H, W, 3)`` world-frame hit points.
    """
    K, R, t, h, w = _check_camera(K, R, t, image_size)
    origin, directions = camera_rays(K, R, t, (h, w))
    if not np.all((origin > room.lo) & (origin < room.hi)):
        raise InputError(f"render: the camera centre {np.round(origin, 3).tolist()} is outside the room "
                         f"{room.lo.tolist()} .. {room.hi.tolist()}")
    depth, surface = ray_room_exit(origin, directions, room.lo, room.hi)
    for i, box in enumerate(room.boxes):
        # Only the pixels that can see the box: most boxes cover a small part of the image.
        window = _box_window(box, K, R, t, h, w)
        if window is None:
            continue
        param, face = ray_box_entry(origin, directions[window], box.lo, box.hi)
        closer = param < depth[window]
        depth[window] = np.where(closer, param, depth[window])
        surface[window] = np.where(closer, NUM_ROOM_SURFACES + 6 * i + face, surface[window])
    return depth, surface, origin + depth[..., None] * directions


def shade_room(room: Room, points: np.ndarray, surface: np.ndarray, lighting: Lighting = Lighting()) -> np.ndarray:
    """``(..., 3)`` float32 RGB in [0, 1] of room points ``(..., 3)`` on surfaces ``(...)``: texture times shading."""
    surfaces = room_surfaces(room)
    atlas = texture_atlas(room)
    origins = np.array([s.origin for s in surfaces])
    maps = []
    for axes, size, offset in (([s.u_axis for s in surfaces], atlas.shapes[:, 1], atlas.offsets[:, 0]),
                               ([s.v_axis for s in surfaces], atlas.shapes[:, 0], atlas.offsets[:, 1])):
        # Texel coordinate as an affine function of the point, per surface; texel centres sit half a
        # texel in from the surface corner. Small per-surface tables gathered per pixel.
        axes = np.array(axes) / TEXEL_SIZE
        coef = np.concatenate([axes, -(axes * origins).sum(axis=1, keepdims=True) - 0.5], axis=1).T
        coord = sum(points[..., k] * np.take(coef[k], surface) for k in range(3)) + np.take(coef[3], surface)
        maps.append(np.clip(coord, 0, np.take(size - 1, surface)) + np.take(offset, surface))
    colour = _bilinear(atlas.image, *maps)
    shading = lighting.shading(np.array([s.normal for s in surfaces])).astype(np.float32)
    return colour * (np.take(shading, surface) / np.float32(255.0))[..., None]


def _bilinear(image: np.ndarray, x: np.ndarray, y: np.ndarray, row_length: int = 1024) -> np.ndarray:
    """``(..., C)`` bilinear samples of ``image (H, W, C)`` at continuous pixel coordinates ``x, y (...)``."""
    # cv2.remap wants 2D maps shorter than 32767 on each side: lay the samples out in rows.
    n = x.size
    pad = -n % row_length
    maps = [np.pad(a.reshape(-1).astype(np.float32), (0, pad)).reshape(-1, row_length) for a in (x, y)]
    out = cv2.remap(image, maps[0], maps[1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    return out.reshape(-1, image.shape[2])[:n].reshape(*x.shape, image.shape[2])


def _tile_sizes(max_side: int) -> np.ndarray:
    """Tile sides of the rasteriser's size groups: 1 to 4, then steps of about 25% up to ``max_side``.

    A face's bounding box is padded to the next tile side, so the steps bound the wasted candidates.
    """
    sizes = [1, 2, 3, 4]
    while sizes[-1] < max_side:
        sizes.append(max(sizes[-1] + 1, int(np.ceil(sizes[-1] * 1.25))))
    return np.asarray(sizes)


def rasterize(points_cam: np.ndarray, faces: np.ndarray, K: np.ndarray, image_size: tuple[int, int],
              depth_limit: np.ndarray | None = None, near: float = NEAR_PLANE,
              max_fragments: int = 1_000_000) -> Fragments:
    """Z-buffer rasterisation of triangles at pixel centres, vectorised over triangles.

    Faces with a vertex nearer than ``near`` are dropped. Faces are grouped by the size of their pixel
    bounding box, padded to a tile size; each group is one ``(faces, rows, cols)`` array of candidate
    pixels, kept where all barycentric coordinates are >= 0 (screen-space barycentrics are affine in
    the pixel, so a tile is two broadcast sums) and where the perspective-correct depth (1/z
    interpolated in screen space) beats both ``depth_limit`` and the other faces. Groups are cut into
    chunks of about ``max_fragments`` candidates to bound memory.

    Args:
        points_cam: ``(V, 3)`` camera-frame vertices.
        faces: ``(F, 3)`` int.
        K: ``(3, 3)`` intrinsics.
        image_size: ``(H, W)``.
        depth_limit: ``(H, W)`` depth already in the image (faces behind it are hidden), default inf.
        near: near plane, metres.
        max_fragments: candidate pixels per chunk.
    Returns:
        the visible face, barycentric coordinates and depth of every pixel.
    """
    h, w = image_size
    zbuf = np.full(h * w, np.inf) if depth_limit is None else np.array(depth_limit, dtype=float).reshape(-1)
    fbuf = np.full(h * w, -1, np.int64)
    bary = np.zeros((3, h * w))
    faces = np.asarray(faces, dtype=np.int64)
    points_cam = np.asarray(points_cam, dtype=float)
    z = points_cam[:, 2]
    uv = (points_cam / np.where(z > 0, z, 1.0)[:, None]) @ K.T
    face_ids = np.nonzero(np.all(z[faces] >= near, axis=1))[0]
    xs, ys = uv[faces[face_ids], 0].T, uv[faces[face_ids], 1].T  # (3, F') each
    umin, vmin = np.maximum(np.ceil(xs.min(axis=0)), 0), np.maximum(np.ceil(ys.min(axis=0)), 0)
    box_w = np.minimum(np.floor(xs.max(axis=0)), w - 1) - umin + 1
    box_h = np.minimum(np.floor(ys.max(axis=0)), h - 1) - vmin + 1
    area = (xs[1] - xs[0]) * (ys[2] - ys[0]) - (xs[2] - xs[0]) * (ys[1] - ys[0])
    keep = (box_w > 0) & (box_h > 0) & (np.abs(area) > 1e-12)
    face_ids, umin, vmin, box_w, box_h, area = (a[keep] for a in (face_ids, umin, vmin, box_w, box_h, area))
    (x0, x1, x2), (y0, y1, y2) = xs[:, keep], ys[:, keep]
    # Barycentric i at pixel (umin + du, vmin + dv) is e_i + a_i du + b_i dv: e_i is its value at the box corner.
    a = np.stack([y1 - y2, y2 - y0, y0 - y1]) / area
    b = np.stack([x2 - x1, x0 - x2, x1 - x0]) / area
    e = np.stack([x1 * y2 - x2 * y1, x2 * y0 - x0 * y2, x0 * y1 - x1 * y0]) / area + a * umin + b * vmin
    # Tiles in float32 (values are O(1) near the box): half the memory traffic of the largest arrays.
    a, b, e = (c.astype(np.float32) for c in (a, b, e))
    inv_depth = 1.0 / z[faces[face_ids]]  # (F', 3)
    sizes = _tile_sizes(max(h, w))
    tile_w, tile_h = np.searchsorted(sizes, box_w), np.searchsorted(sizes, box_h)
    key = tile_h * len(sizes) + tile_w
    order = np.argsort(key, kind="stable")
    groups = np.split(order, np.nonzero(np.diff(key[order]))[0] + 1) if len(order) else []
    for group in groups:
        th, tw = int(sizes[tile_h[group[0]]]), int(sizes[tile_w[group[0]]])
        step = max(1, max_fragments // (th * tw))
        du, dv = np.arange(tw, dtype=np.float32), np.arange(th, dtype=np.float32)
        for start in range(0, len(group), step):
            g = group[start:start + step]
            weights = [(e[i, g, None] + a[i, g, None] * du)[:, None, :] + (b[i, g, None] * dv)[:, :, None]
                       for i in range(3)]  # 3 x (n, th, tw)
            inside = np.minimum(np.minimum(weights[0], weights[1]), weights[2]) >= 0
            fi, vi, ui = np.nonzero(inside)
            u, v = umin[g][fi].astype(np.int64) + ui, vmin[g][fi].astype(np.int64) + vi
            on_image = (u < w) & (v < h)  # tiles are padded past the clipped box
            fi, u, v = fi[on_image], u[on_image], v[on_image]
            wts = [wt[inside][on_image].astype(float) for wt in weights]  # 3 x (N,)
            fid = g[fi]
            inv_z = wts[0] * inv_depth[fid, 0] + wts[1] * inv_depth[fid, 1] + wts[2] * inv_depth[fid, 2]
            pix = v * w + u
            front = np.nonzero(inv_z * zbuf[pix] > 1.0)[0]  # 1/inv_z < zbuf, also for zbuf = inf
            if not front.size:
                continue
            # Nearest fragment per pixel: sort by (pixel, depth), take each pixel's first. One integer
            # key: positive float32 bit patterns sort like the floats.
            depth32 = (1.0 / inv_z[front]).astype(np.float32).view(np.uint32).astype(np.uint64)
            ranked = front[np.argsort((pix[front].astype(np.uint64) << np.uint64(32)) | depth32, kind="stable")]
            sorted_pix = pix[ranked]
            first = np.ones(len(ranked), bool)
            first[1:] = sorted_pix[1:] != sorted_pix[:-1]
            win = ranked[first]
            p = pix[win]
            zbuf[p] = 1.0 / inv_z[win]
            fbuf[p] = face_ids[fid[win]]
            # Perspective-correct barycentrics: screen weights over depth, renormalised.
            for i in range(3):
                bary[i, p] = wts[i][win] * inv_depth[fid[win], i] / inv_z[win]
    return Fragments(fbuf.reshape(h, w), np.moveaxis(bary, 0, -1).reshape(h, w, 3), zbuf.reshape(h, w))


def render_view(room: Room, meshes: Sequence[MeshInstance], K: np.ndarray, R: np.ndarray, t: np.ndarray,
                image_size: tuple[int, int], *, lighting: Lighting = Lighting(), noise_std: float = 0.0,
                noise_seed: int = 0) -> Render:
    """Render people (``meshes``) in ``room`` seen by the OpenCV camera ``K, R, t``.

    Args:
        room: the room; the camera centre must be inside it.
        meshes: meshes in the world frame; ``Render.instance`` indexes this sequence.
        K: ``(3, 3)`` intrinsics.
        R: ``(3, 3)`` world-to-camera rotation.
        t: ``(3,)`` world-to-camera translation.
        image_size: ``(H, W)``.
        lighting: the fixed light.
        noise_std: standard deviation of Gaussian sensor noise as a fraction of full scale (0 = exact
            colours); depth and instances are never noisy.
        noise_seed: seed of that noise.
    Returns:
        RGB, z-depth and instance map.
    """
    K, R, t, h, w = _check_camera(K, R, t, image_size)
    if len(meshes) > np.iinfo(np.int16).max:
        raise InputError(f"render_view: at most {np.iinfo(np.int16).max} meshes, got {len(meshes)}")
    depth, surface, points = cast_room(room, K, R, t, (h, w))
    rgb = shade_room(room, points, surface, lighting)
    instance = np.full((h, w), -1, np.int16)
    if meshes:
        vertices = np.concatenate([m.vertices for m in meshes])
        offsets = np.cumsum([0] + [len(m.vertices) for m in meshes])
        faces = np.concatenate([m.faces + o for m, o in zip(meshes, offsets)])
        face_instance = np.repeat(np.arange(len(meshes)), [len(m.faces) for m in meshes])
        colours = np.concatenate([m.vertex_colors for m in meshes])
        frags = rasterize(vertices @ R.T + t, faces, K, (h, w), depth_limit=depth)
        hit = frags.face >= 0
        if np.any(hit):
            # Interpolate normals, positions and colours at once: (N, 1, 3) @ (N, 3, 9).
            attributes = np.concatenate([vertex_normals(vertices, faces), vertices, colours], axis=1)
            b = frags.barycentric[hit][:, None, :]
            normals, body_points, colour = np.split((b @ attributes[faces[frags.face[hit]]])[:, 0], 3, axis=1)
            normals /= np.maximum(np.linalg.norm(normals, axis=-1, keepdims=True), 1e-12)
            # Two-sided: turn normals towards the camera so winding does not matter.
            away = ((body_points - (-R.T @ t)) * normals).sum(-1) > 0
            normals[away] *= -1.0
            rgb[hit] = colour * lighting.shading(normals)[:, None]
            instance[hit] = face_instance[frags.face[hit]]
            depth = frags.depth
    if noise_std > 0:
        rgb = rgb + np.random.default_rng(noise_seed).normal(0.0, noise_std, rgb.shape)
    rgb8 = np.clip(rgb * 255.0 + 0.5, 0, 255).astype(np.uint8)
    return Render(rgb8, depth.astype(np.float32), instance)
