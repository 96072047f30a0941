"""A rerun recording (``.rrd``) to explore the reconstruction in the rerun viewer (``rerun scene.rrd``).

Entities (timeline ``frame``: the video frame index; the recording also carries ``time`` in seconds):

- ``world``: view coordinates right-handed z-up; a static transform turns the reconstruction's world so
  that its estimated up direction is +z (:func:`multithumbs.export.posed.rotation_to_z_up`).
- ``world/people/<id>``: the person's mesh (``Mesh3D``) at every valid frame, coloured by global id;
  cleared (``Clear``) where the person is not valid. Faces and colours are logged when a person appears
  and only vertex positions afterwards.
- ``world/people/<id>/joints``: the 24 SMPL joints as points.
- ``world/trajectories/<id>``: static pelvis path (a line strip per shot, so cuts do not draw jumps).
- ``world/camera``: ``Transform3D`` (camera-to-world) and ``Pinhole`` (OpenCV axes: right, down, forward)
  per frame; ``world/camera/image``: the video frame as JPEG when frames are given, so the viewer's 2D
  view overlays the meshes on the footage.
- ``world/scene_points/cut_<k>``: static scene points of each cut (world frame), when given.
- ``cuts``: a text log entry at every cut frame.
"""

from __future__ import annotations

from pathlib import Path
from typing import Iterable, Sequence

import numpy as np

from multithumbs.errors import InputError
from multithumbs.export.cameras import check_scene_points
from multithumbs.export.files import atomic_output
from multithumbs.export.posed import camera_centres, shot_index
from multithumbs.types import WorldResult
from multithumbs.viz.palette import id_color_u8

APPLICATION_ID = "multithumbs"


def write_rrd(path: str | Path, result: WorldResult, vertices: np.ndarray, joints: np.ndarray, faces: np.ndarray,
              to_z_up: np.ndarray, scene_points: Sequence[np.ndarray] | None = None,
              frames_rgb: Iterable[np.ndarray] | None = None, jpeg_quality: int = 80) -> Path:
    """Write the recording (module docstring) to ``path`` atomically.

    Args:
        path: output ``.rrd``.
        result: the reconstruction.
        vertices: ``(P, T, V, 3)`` posed world vertices.
        joints: ``(P, T, 24, 3)`` posed world joints.
        faces: ``(F, 3)``.
        to_z_up: ``(3, 3)`` rotation from the world to rerun's z-up display frame.
        scene_points: optional world-frame points, one ``(N, 3)`` array per cut.
        frames_rgb: optional iterable of the video's ``(H, W, 3)`` RGB frames in order (one per result frame).
        jpeg_quality: JPEG quality of the logged frames.
    """
    import cv2
    import rerun as rr

    p_count, t_count = result.valid.shape
    if np.shape(vertices)[:2] != (p_count, t_count) or np.shape(joints)[:2] != (p_count, t_count):
        raise InputError(f"vertices/joints: expected leading shape ({p_count}, {t_count})")
    points = check_scene_points(scene_points, int(result.cut_frames.size))
    faces = np.asarray(faces, np.uint32)
    h, w = result.image_size
    shots = shot_index(result)
    centres = camera_centres(result)
    frame_iter = iter(frames_rgb) if frames_rgb is not None else None

    rec = rr.RecordingStream(APPLICATION_ID)
    with atomic_output(path) as tmp:
        rec.save(str(tmp))
        try:
            rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
            rec.log("world", rr.Transform3D(mat3x3=np.asarray(to_z_up, np.float32)), static=True)
            for k, pts in enumerate(points):
                rec.log(f"world/scene_points/cut_{k}", rr.Points3D(pts.astype(np.float32), radii=0.01,
                                                                    colors=[(150, 150, 150)]), static=True)
            for p in range(p_count):
                gid = int(result.person_ids[p])
                strips = [joints[p, np.nonzero((shots == s) & result.valid[p])[0], 0].astype(np.float32)
                          for s in range(result.cut_frames.size + 1)]
                strips = [s for s in strips if len(s) > 1]
                if strips:
                    rec.log(f"world/trajectories/{gid}", rr.LineStrips3D(strips, colors=[id_color_u8(gid)]),
                            static=True)
            shown = np.zeros(p_count, bool)
            for f in range(t_count):
                rec.set_time("frame", sequence=f)
                rec.set_time("time", duration=f / result.fps)
                if f in set(result.cut_frames.tolist()):
                    rec.log("cuts", rr.TextLog(f"cut: shot {shots[f] - 1} -> shot {shots[f]} at frame {f}"))
                rec.log("world/camera", rr.Transform3D(translation=centres[f].astype(np.float32),
                                                       mat3x3=np.asarray(result.R[f].T, np.float32)))
                rec.log("world/camera", rr.Pinhole(image_from_camera=np.asarray(result.K[f], np.float32),
                                                   resolution=[w, h], camera_xyz=rr.ViewCoordinates.RDF))
                if frame_iter is not None:
                    rgb = next(frame_iter, None)
                    if rgb is None:
                        raise InputError(f"frames: the video ends before frame {f} of {t_count}")
                    ok, jpg = cv2.imencode(".jpg", cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR),
                                           [cv2.IMWRITE_JPEG_QUALITY, int(jpeg_quality)])
                    rec.log("world/camera/image", rr.EncodedImage(contents=jpg.tobytes(), media_type="image/jpeg"))
                for p in range(p_count):
                    entity = f"world/people/{int(result.person_ids[p])}"
                    if not result.valid[p, f]:
                        if shown[p]:
                            rec.log(entity, rr.Clear(recursive=True))
                            shown[p] = False
                        continue
                    positions = np.asarray(vertices[p, f], np.float32)
                    if shown[p]:
                        rec.log(entity, rr.Mesh3D.from_fields(vertex_positions=positions))
                    else:  # (re)appearing: the whole mesh, since a Clear removed faces and colours too
                        rec.log(entity, rr.Mesh3D(vertex_positions=positions, triangle_indices=faces,
                                                  albedo_factor=[*id_color_u8(int(result.person_ids[p])), 255]))
                        shown[p] = True
                    rec.log(f"{entity}/joints", rr.Points3D(np.asarray(joints[p, f], np.float32), radii=0.02,
                                                             colors=[id_color_u8(int(result.person_ids[p]))]))
            rec.flush()
        finally:
            rec.disconnect()
    return Path(path)
