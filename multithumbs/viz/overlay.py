"""Overlay video: every person's mesh drawn over the input frames on the CPU, coloured by global id.

Meshes come from the body model (:meth:`multithumbs.body.model.BodyModel.forward`) and are rasterised by
the synthetic world's z-buffer (:func:`multithumbs.synth.render.rasterize`) without a room: people are
shaded by a headlight in the camera frame (so the picture does not depend on the world's up axis) and
blended over the frame. Each frame shows its index and shot, a timeline with the cuts, a ``CUT`` badge
and red border on the first frames after a cut, and ``#id`` labels; with ground truth the truth is drawn
the same way in a second panel on the right (coloured by the true ids), and the result's people are
coloured by the truth person the evaluation paired them with (:mod:`multithumbs.viz.pairing`: a mere
relabelling of ids looks the same in both panels, a real identity switch at a cut shows as a person
changing colour at the cut); the ``#id`` labels stay the result's own ids.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import cv2
import numpy as np
import torch

from multithumbs.conventions import NUM_BETAS
from multithumbs.errors import InputError
from multithumbs.export.files import atomic_output
from multithumbs.geometry import vertex_normals
from multithumbs.synth.render import Lighting, rasterize
from multithumbs.types import GroundTruth, WorldResult
from multithumbs.video import iter_frames
from multithumbs.viz.labels import draw_label
from multithumbs.viz.pairing import TruthColouring, colouring_for
from multithumbs.viz.palette import id_color

HEADLIGHT = Lighting(direction=(0.0, -0.5, -1.0), ambient=0.35, diffuse=0.7)
"""Shading of overlaid meshes, with the light direction in the CAMERA frame: from the camera, a little
from above (camera +y points down)."""

CUT_BADGE_SECONDS = 0.4
"""How long after a cut the ``CUT`` badge and red border stay on screen."""


@dataclass(frozen=True)
class PeopleLayer:
    """People rendered from one camera, to composite over a frame.

    Attributes:
        rgb: ``(H, W, 3)`` float32 shaded colour in [0, 1] where ``person >= 0``.
        person: ``(H, W)`` int16 index into the meshes that were rendered, -1 where none is visible.
        anchors: ``(N, 2)`` float pixel above each mesh's head (top centre of its projected bounding box),
            NaN for a mesh not in front of the camera.
    """

    rgb: np.ndarray
    person: np.ndarray
    anchors: np.ndarray


def render_people(vertices: np.ndarray, faces: np.ndarray, colors: np.ndarray, K: np.ndarray, R: np.ndarray,
                  t: np.ndarray, image_size: tuple[int, int], lighting: Lighting = HEADLIGHT) -> PeopleLayer:
    """Rasterise meshes seen by one OpenCV camera.

    Args:
        vertices: ``(N, V, 3)`` world-frame vertices of N meshes sharing ``faces``.
        faces: ``(F, 3)`` int.
        colors: ``(N, 3)`` float RGB in [0, 1], one per mesh.
        K, R, t: ``(3, 3)``, ``(3, 3)``, ``(3,)`` camera (world-to-camera).
        image_size: ``(H, W)``.
        lighting: shading, light direction in the camera frame.
    """
    h, w = (int(s) for s in image_size)
    vertices = np.asarray(vertices, np.float64)
    if vertices.ndim != 3 or vertices.shape[-1] != 3:
        raise InputError(f"vertices: expected shape (N, V, 3), got {vertices.shape}")
    n, v_count = vertices.shape[:2]
    colors = np.asarray(colors, np.float64).reshape(n, 3)
    rgb = np.zeros((h, w, 3), np.float32)
    person = np.full((h, w), -1, np.int16)
    anchors = np.full((n, 2), np.nan)
    if n == 0:
        return PeopleLayer(rgb, person, anchors)
    faces = np.asarray(faces, np.int64)
    cam = vertices @ np.asarray(R, np.float64).T + np.asarray(t, np.float64)  # (N, V, 3)
    for i in range(n):
        front = cam[i, :, 2] > 0.05
        if front.any():
            uv = cam[i, front, :2] / cam[i, front, 2:3] * np.diag(K)[:2] + K[:2, 2]
            anchors[i] = [0.5 * (uv[:, 0].min() + uv[:, 0].max()), uv[:, 1].min()]
    flat = cam.reshape(-1, 3)
    all_faces = (faces[None] + (np.arange(n) * v_count)[:, None, None]).reshape(-1, 3)
    frags = rasterize(flat, all_faces, np.asarray(K, np.float64), (h, w))
    hit = frags.face >= 0
    if hit.any():
        face = frags.face[hit]
        normals = vertex_normals(cam, faces).reshape(-1, 3)
        corners = all_faces[face]  # (M, 3)
        b = frags.barycentric[hit]
        normal = (b[:, :, None] * normals[corners]).sum(axis=1)
        point = (b[:, :, None] * flat[corners]).sum(axis=1)
        normal /= np.maximum(np.linalg.norm(normal, axis=-1, keepdims=True), 1e-12)
        normal[(normal * point).sum(-1) > 0] *= -1.0  # two-sided: face the camera
        mesh = face // len(faces)
        rgb[hit] = (colors[mesh] * lighting.shading(normal)[:, None]).clip(0, 1)
        person[hit] = mesh
    return PeopleLayer(rgb, person, anchors)


def composite(frame: np.ndarray, layer: PeopleLayer, opacity: float = 0.7) -> np.ndarray:
    """``(H, W, 3)`` uint8: ``layer`` blended over the RGB ``frame`` with ``opacity`` where people are."""
    out = frame.astype(np.float32)
    hit = layer.person >= 0
    out[hit] = (1 - opacity) * out[hit] + opacity * 255.0 * layer.rgb[hit]
    return np.clip(out + 0.5, 0, 255).astype(np.uint8)


def pose_frame(world: WorldResult, frame: int, body) -> tuple[np.ndarray, np.ndarray]:
    """The valid people of one frame: ``rows (N,)`` of ``world`` and their world ``vertices (N, V, 3)``."""
    rows = np.nonzero(world.valid[:, frame])[0]
    if rows.size == 0:
        return rows, np.zeros((0, int(body.num_vertices), 3))
    with torch.no_grad():
        out = body.forward(world.global_orient[rows, frame], world.body_pose[rows, frame],
                           np.asarray(world.betas[rows]).reshape(-1, NUM_BETAS), world.transl[rows, frame])
    return rows, out.vertices.detach().cpu().double().numpy()


def render_world_frame(world: WorldResult, frame: int, body,
                       colors: np.ndarray | None = None) -> tuple[np.ndarray, PeopleLayer]:
    """Render the valid people of ``world`` at ``frame`` through that frame's camera.

    Args:
        colors: optional ``(P, 3)`` float RGB per person of ``world`` (default: the id colours).
    Returns:
        ``ids (N,)`` the global ids of the rendered people (``layer.person`` indexes them) and the layer.
    """
    rows, vertices = pose_frame(world, frame, body)
    ids = np.asarray(world.person_ids)[rows]
    if colors is not None:
        colors = np.asarray(colors, np.float64).reshape(world.num_people, 3)[rows]
    else:
        colors = np.stack([id_color(i) for i in ids]) if ids.size else np.zeros((0, 3))
    layer = render_people(vertices, body.faces, colors, world.K[frame], world.R[frame], world.t[frame],
                          world.image_size)
    return ids, layer


def _text(image: np.ndarray, text: str, org: tuple[int, int], scale: float, color=(255, 255, 255)) -> None:
    draw_label(image, text, org, scale, color)


def annotate(image: np.ndarray, world: WorldResult, frame: int, ids: np.ndarray, layer: PeopleLayer,
             title: str = "", colors: np.ndarray | None = None, legend: str = "") -> np.ndarray:
    """Draw the frame/shot header, the cut timeline, the cut badge and person labels on ``image`` (in place).

    Args:
        ids: ``(N,)`` global ids of the rendered people (the labels' text).
        colors: optional ``(N, 3)`` float RGB of the labels, one per rendered person (default: id colours).
        legend: optional line above the timeline saying what the colours mean.
    """
    h, w = image.shape[:2]
    scale = max(0.35, min(1.0, w / 1100))
    cuts = np.asarray(world.cut_frames)
    shot = int(np.searchsorted(cuts, frame, side="right"))
    header = f"{title + '  ' if title else ''}frame {frame}  shot {shot}"
    _text(image, header, (8, int(22 * scale + 6)), scale)
    if legend:
        # Just above the timeline: the person labels sit over heads, near the top, where it would collide.
        _text(image, legend, (8, h - 18), scale * 0.75)
    for i, (gid, (u, v)) in enumerate(zip(ids, layer.anchors)):
        if np.isfinite(u) and -20 < u < w + 20 and -20 < v < h:
            rgb = id_color(int(gid)) if colors is None else np.asarray(colors[i], np.float64)
            _text(image, f"#{int(gid)}", (int(u) - 12, int(max(v - 6, 14))), scale * 0.9,
                  tuple(int(round(c * 255)) for c in rgb))
    # Timeline: a bar at the bottom with a tick per cut and the current position.
    bar_y = h - 8
    n = max(world.num_frames - 1, 1)
    cv2.line(image, (4, bar_y), (w - 5, bar_y), (235, 235, 235), 2)
    for c in cuts:
        x = int(4 + (w - 9) * c / n)
        cv2.line(image, (x, bar_y - 6), (x, bar_y + 4), (230, 40, 40), 2)
    x = int(4 + (w - 9) * frame / n)
    cv2.circle(image, (x, bar_y), 4, (255, 210, 0), -1)
    last_cut = cuts[cuts <= frame].max() if (cuts <= frame).any() else None
    if last_cut is not None and frame - last_cut < max(1, int(round(CUT_BADGE_SECONDS * world.fps))):
        cv2.rectangle(image, (1, 1), (w - 2, h - 2), (230, 40, 40), 4)
        _text(image, f"CUT {shot - 1}|{shot}", (w - int(175 * scale) - 8, int(22 * scale + 6)), scale,
              (255, 90, 90))
    return image


def overlay_image(frame_rgb: np.ndarray, world: WorldResult, frame: int, body, title: str = "",
                  opacity: float = 0.7, colouring: TruthColouring | None = None
                  ) -> tuple[np.ndarray, np.ndarray, PeopleLayer]:
    """One annotated overlay panel: ``(image (H, W, 3) uint8, ids, layer)``.

    Args:
        colouring: optional colours of ``world``'s people and their legend (default: the id colours).
    """
    colors = None if colouring is None else colouring.colors
    ids, layer = render_world_frame(world, frame, body, colors)
    image = composite(frame_rgb, layer, opacity)
    shown = None if colors is None else np.asarray(colors)[np.nonzero(world.valid[:, frame])[0]]
    # The labels keep the result's own ids, which now differ from their colour's truth id: say so.
    legend = colouring.legend + " (labels: result ids)" if colouring is not None and colouring.legend else ""
    return annotate(image, world, frame, ids, layer, title, shown, legend), ids, layer


def check_video_matches(result: WorldResult, frame_rgb: np.ndarray, video_path: Path) -> None:
    """Raise :class:`InputError` when a decoded frame's size is not the result's image size."""
    if tuple(frame_rgb.shape[:2]) != tuple(result.image_size):
        raise InputError(f"{video_path}: frames are {frame_rgb.shape[1]}x{frame_rgb.shape[0]} but the result "
                         f"expects {result.image_size[1]}x{result.image_size[0]}")


def write_overlay_video(path: str | Path, result: WorldResult, video_path: str | Path, body,
                        truth: GroundTruth | None = None, opacity: float = 0.7,
                        progress: Callable[[int, int], None] | None = None,
                        colouring: TruthColouring | None = None) -> Path:
    """Write the overlay video (module docstring) as MPEG-4, atomically.

    Args:
        path: output ``.mp4``.
        result: the reconstruction (its frames must be the video's frames).
        video_path: the input video.
        body: the body model.
        truth: optional ground truth, drawn in a second panel on the right.
        opacity: mesh opacity over the frame.
        progress: optional ``progress(done, total)`` after each frame.
        colouring: the result's colours (:func:`multithumbs.viz.pairing.colouring_for`); by default computed
            here: by the paired truth person with truth, by the result's ids without.
    Raises:
        InputError: the video cannot be read, or its size or frame count differs from the result's.
    """
    video_path = Path(video_path)
    t_count = result.num_frames
    if truth is not None and truth.world.num_frames != t_count:
        raise InputError(f"truth: {truth.world.num_frames} frames, but the result has {t_count}")
    if colouring is None and truth is not None:
        from multithumbs.export.posed import posed_joints

        colouring = colouring_for(result, posed_joints(result, body), truth, posed_joints(truth.world, body))
    h, w = result.image_size
    width = 2 * w if truth is not None else w
    with atomic_output(path) as tmp:
        writer = cv2.VideoWriter(str(tmp), cv2.VideoWriter_fourcc(*"mp4v"), float(result.fps), (width, h))
        if not writer.isOpened():
            raise InputError(f"{path}: OpenCV cannot open an MPEG-4 writer here")
        count = 0
        try:
            for f, rgb in enumerate(iter_frames(video_path, 0, t_count + 1)):
                if f == t_count:
                    raise InputError(f"{video_path}: the video has more frames than the result ({t_count})")
                check_video_matches(result, rgb, video_path)
                panel, _, _ = overlay_image(rgb, result, f, body, "result" if truth is not None else "", opacity,
                                            colouring)
                if truth is not None:
                    gt_panel, _, _ = overlay_image(rgb, truth.world, f, body, "ground truth", opacity)
                    panel = np.concatenate([panel, gt_panel], axis=1)
                writer.write(cv2.cvtColor(panel, cv2.COLOR_RGB2BGR))
                count += 1
                if progress is not None:
                    progress(count, t_count)
        finally:
            writer.release()
        if count < t_count:
            raise InputError(f"{video_path}: the video has {count} frames but the result has {t_count}")
    return Path(path)
