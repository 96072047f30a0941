"""The plain-Python reference chain: per-shot inputs to one :class:`WorldResult` (paper §3, DESIGN §1).

``run_video`` runs every stage in order; each stage is also a function of its own so that the Prefect
tasks (``tasks/``) can cache them one by one:

1. :func:`boundary_people` — the people of the two frames around each cut, posed once;
2. :func:`multithumbs.method.align.align_boundary` — scale and three-stage alignment per cut;
3. :func:`multithumbs.world_placement.propagate` — every camera and every track's root into one world frame, cut by cut;
4. :func:`reidentify` — global identities: fragments of one person linked within shots, then across cuts;
5. :func:`assemble` and :func:`multithumbs.method.post.post_process` — world tracks and their refinement;
6. :func:`to_world_result`.

Variants (paper Table 3 and baselines): ``full``; ablations ``no_cam`` (no camera refinement in stage 3),
``no_post``, ``no_stage`` (every parameter jointly from the estimator's placement), ``no_align``; baselines
``independent_shots`` (each shot in its own camera-tracking frame, identities linked the way single-shot
trackers such as PHALP link them across a cut: appearance and pose, no location), ``appearance_only`` and
``distance_only`` re-identification.
"""

from __future__ import annotations

import dataclasses
from typing import Sequence

import numpy as np
import torch

from multithumbs.appearance import mean_descriptor
from multithumbs.errors import InputError
from multithumbs.geometry import reexpress_for_intrinsics
from multithumbs.method.align import AlignedBoundary, BoundaryPeople, align_boundary
# The settings live without torch in multithumbs.method.config; re-exported here as before.
from multithumbs.method.config import (VARIANTS, AlignConfig, MethodConfig, PostConfig, ReidConfig,  # noqa: F401
                                       variant_config)
from multithumbs.method.post import PostInput, post_process
from multithumbs.method.identities import Identities, link_fragments, reidentify  # noqa: F401  (re-exported)
from multithumbs.world_placement import Placement, propagate
from multithumbs.types import CameraTrajectory, PersonTracks, SharedSpace, Shots, WorldResult

# ----------------------------------------------------------------------------------------------------
# 1. Boundary people


def boundary_people(before: PersonTracks, after: PersonTracks, body, window: int = 3,
                    K: np.ndarray | None = None, appearance_window: int = 15) -> BoundaryPeople:
    """The people around a cut — the last frame of ``before``, the first of ``after`` — posed once.

    A person the detector missed at the boundary frame itself is taken from their detection nearest to it
    within ``window`` frames (people move centimetres in that time), so one missed frame does not leave
    them unaligned; ``track_frame`` records which frame was used. ``K`` ``(2, 3, 3)``: the boundary
    cameras' intrinsics (the shared space's); the estimator's camera-frame roots are re-expressed for them
    (:func:`multithumbs.geometry.reexpress_for_intrinsics`; default: kept as the tracks give them).
    Appearance: each person's mean descriptor over their ``appearance_window`` detections nearest the cut.
    """
    sides = []
    for tr, last in ((before, True), (after, False)):
        frames = np.arange(tr.num_frames)
        near = frames[-window:][::-1] if last else frames[:window]
        picks = []
        for i in range(tr.num_people):
            hits = near[tr.valid[i, near]]
            if len(hits):
                picks.append((i, int(hits[0])))
        sides.append((tr, picks))
    p_max = max(1, max(len(picks) for _, picks in sides))
    h, w = before.image_size
    v_count = body.num_vertices
    out = {
        "present": np.zeros((2, p_max), bool), "track_index": np.full((2, p_max), -1),
        "track_frame": np.full((2, p_max), -1),
        "local_vertices": np.zeros((2, p_max, v_count, 3)), "local_joints": np.zeros((2, p_max, 24, 3)),
        "orient_cam": np.zeros((2, p_max, 3)), "pelvis_cam": np.zeros((2, p_max, 3)),
        "keypoints": np.zeros((2, p_max, 24, 3)), "masks": np.zeros((2, p_max, h, w), bool),
    }
    appearance = []
    for k, (tr, picks) in enumerate(sides):
        if not picks:
            continue
        idx = np.array([i for i, _ in picks])
        f = np.array([fr for _, fr in picks])
        with torch.no_grad():
            posed = body.forward(np.zeros((len(idx), 3)), tr.body_pose[idx, f], tr.betas[idx])
        verts, joints = posed.vertices.double().numpy(), posed.joints.double().numpy()
        n = len(idx)
        out["present"][k, :n] = True
        out["track_index"][k, :n] = idx
        out["track_frame"][k, :n] = f
        out["local_vertices"][k, :n] = verts - joints[:, :1]
        out["local_joints"][k, :n] = joints - joints[:, :1]
        out["orient_cam"][k, :n] = tr.global_orient[idx, f]
        pelvis_cam = tr.transl[idx, f] + joints[:, 0]
        out["pelvis_cam"][k, :n] = pelvis_cam if K is None else reexpress_for_intrinsics(pelvis_cam, tr.K, K[k])
        kp = tr.keypoints2d[idx, f]
        out["keypoints"][k, :n, :, :] = kp[:, :24] if kp.shape[1] >= 24 else 0.0
        for j, (i, fr) in enumerate(picks):
            out["masks"][k, j] = tr.mask(i, fr)
            # Appearance over the frames next to the cut, as re-identification takes it.
            seen = np.nonzero(tr.valid[i])[0]
            near_cut = seen[-appearance_window:] if k == 0 else seen[:appearance_window]
            appearance.append((k, j, mean_descriptor(tr.appearance[i, near_cut], tr.appearance_valid[i, near_cut])))
    descriptors = np.zeros((2, p_max, before.appearance.shape[-1]))
    for k, j, d in appearance:
        descriptors[k, j] = d
    return BoundaryPeople(faces=body.faces, appearance=descriptors, **out)


# ----------------------------------------------------------------------------------------------------
# 3-4. Propagation (multithumbs.world_placement) and identities (multithumbs.method.identities)


# ----------------------------------------------------------------------------------------------------
# 5-6. Assembly, post-processing, result


def assemble(shots: Shots, tracks: Sequence[PersonTracks], placement: Placement, ids: Identities) -> PostInput:
    """World tracks ``(G, T, ...)`` of every global person, ready for post-processing."""
    G, T = ids.num_people, shots.num_frames
    orient, transl = np.zeros((G, T, 3)), np.zeros((G, T, 3))
    body_pose, keypoints = np.zeros((G, T, 23, 3)), np.zeros((G, T, 24, 3))
    valid = np.zeros((G, T), bool)
    betas_sum, betas_w = np.zeros((G, 10)), np.zeros(G)
    for k, (tr, (a, b)) in enumerate(zip(tracks, shots.ranges)):
        for i, g in enumerate(ids.global_ids[k]):
            v = tr.valid[i]
            if valid[g, a:b][v].any():
                raise InputError(f"shot {k}: two tracks were given global id {g}")
            sl = np.arange(a, b)[v]
            orient[g, sl], transl[g, sl] = placement.orient[k][i, v], placement.transl[k][i, v]
            body_pose[g, sl] = tr.body_pose[i, v]
            if tr.keypoints2d.shape[2] >= 24:
                keypoints[g, sl] = tr.keypoints2d[i, v, :24]
            valid[g, sl] = True
            betas_sum[g] += v.sum() * tr.betas[i]
            betas_w[g] += v.sum()
    betas = betas_sum / np.maximum(betas_w, 1)[:, None]
    h, w = tracks[0].image_size
    return PostInput(orient, body_pose, betas, transl, valid, keypoints, placement.K, placement.R, placement.t,
                     shots.cut_frames, ids.matched_at_cut, (h, w))


def to_world_result(shots: Shots, tracks: Sequence[PersonTracks], world: PostInput, ids: Identities,
                    diagnostics: dict[str, np.ndarray]) -> WorldResult:
    """The final :class:`WorldResult`."""
    id_map = np.array([[k, int(tr.track_ids[i]), int(g)] for k, tr in enumerate(tracks)
                       for i, g in enumerate(ids.global_ids[k])], dtype=np.int64).reshape(-1, 3)
    return WorldResult(
        person_ids=np.arange(world.valid.shape[0]), global_orient=world.global_orient, body_pose=world.body_pose,
        betas=world.betas, transl=world.transl, valid=world.valid, K=world.K, R=world.R, t=world.t,
        cut_frames=shots.cut_frames, fps=shots.fps, image_size=world.image_size, id_map=id_map,
        keypoints2d=world.keypoints, diagnostics=diagnostics)


def check_inputs(shots: Shots, tracks: Sequence[PersonTracks], trajectories: Sequence[CameraTrajectory],
                 spaces: Sequence[SharedSpace]) -> None:
    """Raise :class:`InputError` when the per-shot inputs do not fit the shots."""
    if len(tracks) != shots.num_shots or len(trajectories) != shots.num_shots:
        raise InputError(f"inputs: {shots.num_shots} shots but {len(tracks)} track sets and "
                         f"{len(trajectories)} camera trajectories")
    if len(spaces) != shots.num_shots - 1:
        raise InputError(f"inputs: {shots.num_shots - 1} cuts but {len(spaces)} shared spaces")
    for k, ((a, b), tr, traj) in enumerate(zip(shots.ranges, tracks, trajectories)):
        if tr.num_frames != b - a or traj.num_frames != b - a:
            raise InputError(f"shot {k}: {b - a} frames but tracks have {tr.num_frames} and the camera "
                             f"trajectory {traj.num_frames}")
        for name in ("global_orient", "body_pose", "transl", "betas", "keypoints2d"):
            arr = getattr(tr, name)
            bad = ~np.isfinite(arr)
            if name in ("global_orient", "transl", "keypoints2d", "body_pose"):
                bad = bad.reshape(*arr.shape[:2], int(np.prod(arr.shape[2:]))).any(-1) & tr.valid
            if bad.any():
                raise InputError(f"shot {k}: PersonTracks.{name} has non-finite values in valid frames")
    for c, (space, cut) in enumerate(zip(spaces, shots.cut_frames)):
        if space.cut_frame != cut:
            raise InputError(f"cut {c}: shared space is for frame {space.cut_frame}, the cut is at {cut}")


def sanitize_tracks(tracks: PersonTracks) -> PersonTracks:
    """Drop tracks with fewer than one valid frame (nothing to place) — a documented outcome, not an error."""
    keep = tracks.valid.any(axis=1)
    if keep.all():
        return tracks
    arrays = {f.name: getattr(tracks, f.name) for f in dataclasses.fields(tracks)}
    for name, value in arrays.items():
        if isinstance(value, np.ndarray) and value.ndim >= 1 and value.shape[0] == len(keep) and name != "K":
            arrays[name] = value[keep]
    return PersonTracks(**arrays)


def align_cuts(shots: Shots, tracks: Sequence[PersonTracks], spaces: Sequence[SharedSpace], body,
               config: MethodConfig = MethodConfig()) -> list[AlignedBoundary]:
    """Stages 1-2 for every cut (nothing for the ``independent_shots`` baseline)."""
    if config.independent_shots:
        return []
    return [align_boundary(boundary_people(tracks[c], tracks[c + 1], body, K=space.K), space, config.align,
                           skip=config.skip_align) for c, space in enumerate(spaces)]


def finish_video(shots: Shots, tracks: Sequence[PersonTracks], trajectories: Sequence[CameraTrajectory],
                 aligned: Sequence[AlignedBoundary], body, config: MethodConfig = MethodConfig()) -> WorldResult:
    """Stages 3-6: propagation, re-identification, assembly, post-processing, the result."""
    placement = propagate(shots, tracks, trajectories, aligned, body, independent=config.independent_shots,
                          propagate_orientation=config.propagate_orientation)
    ids = reidentify(tracks, placement, config.reid, config.appearance_window, shots.fps)
    return finish_world(shots, tracks, aligned, placement, ids, body, config)


def finish_world(shots: Shots, tracks: Sequence[PersonTracks], aligned: Sequence[AlignedBoundary],
                 placement: Placement, ids: Identities, body, config: MethodConfig = MethodConfig()) -> WorldResult:
    """Stages 5-6 after re-identification: assembly, post-processing and the result with its diagnostics."""
    world, post_losses = post_processed_world(shots, tracks, placement, ids, body, config)
    diagnostics = world_diagnostics(aligned, placement, ids)
    if post_losses is not None:
        diagnostics["post_loss"] = post_losses
    return to_world_result(shots, tracks, world, ids, diagnostics)


def post_processed_world(shots: Shots, tracks: Sequence[PersonTracks], placement: Placement, ids: Identities,
                         body, config: MethodConfig = MethodConfig()) -> tuple[PostInput, np.ndarray | None]:
    """The assembled world tracks after post-processing (as assembled for ``no_post``), and its loss curve.

    Depends on ``ids`` only through ``global_ids`` and ``matched_at_cut``: variants whose re-identification
    agrees share it (:func:`multithumbs.bench.run_scene`).
    """
    world = assemble(shots, tracks, placement, ids)
    if config.skip_post:
        return world, None
    out = post_process(world, body, config.post)
    world = dataclasses.replace(world, global_orient=out.global_orient, body_pose=out.body_pose,
                                betas=out.betas, transl=out.transl)
    return world, out.losses


CAMERAS_FROM = ("scene", "people", "none")
"""Codes of the ``cameras_from_cut{c}`` diagnostic (:attr:`AlignedBoundary.cameras_from`)."""


def world_diagnostics(aligned: Sequence[AlignedBoundary], placement: Placement, ids: Identities
                      ) -> dict[str, np.ndarray]:
    """Alignment losses and scales, trajectory scales and re-ID cost matrices, by name."""
    diagnostics: dict[str, np.ndarray] = {}
    for c, result in enumerate(aligned):
        diagnostics[f"align_loss_cut{c}"] = result.losses
        diagnostics[f"space_scale_cut{c}"] = np.float64(result.scale)
        diagnostics[f"cameras_from_cut{c}"] = np.int64(CAMERAS_FROM.index(result.cameras_from))
    diagnostics["trajectory_scales"] = placement.trajectory_scales
    for c, m in enumerate(ids.matchings):
        diagnostics[f"reid_cost_cut{c}"] = m.cost
        diagnostics[f"reid_distance_cut{c}"] = m.distance
        diagnostics[f"reid_pairs_cut{c}"] = m.pairs
        diagnostics[f"reid_before_ids_cut{c}"] = ids.before_ids[c]
    return diagnostics


def prepare_inputs(shots: Shots, tracks: Sequence[PersonTracks], trajectories: Sequence[CameraTrajectory],
                   spaces: Sequence[SharedSpace]) -> list[PersonTracks]:
    """Drop empty tracks and check that the inputs fit the shots (:class:`InputError` otherwise)."""
    tracks = [sanitize_tracks(tr) for tr in tracks]
    check_inputs(shots, tracks, trajectories, spaces)
    return tracks


def run_video(shots: Shots, tracks: Sequence[PersonTracks], trajectories: Sequence[CameraTrajectory],
              spaces: Sequence[SharedSpace], body, config: MethodConfig = MethodConfig()) -> WorldResult:
    """The whole method in plain Python (module docstring lists the stages)."""
    tracks = prepare_inputs(shots, tracks, trajectories, spaces)
    aligned = align_cuts(shots, tracks, spaces, body, config)
    return finish_video(shots, tracks, trajectories, aligned, body, config)


def run_video_file(video_path, perception: str, body, intrinsics: np.ndarray | None = None,
                   config: MethodConfig = MethodConfig(), trust_pickle: bool = False,
                   cuts: Sequence[int] | None = None) -> WorldResult:
    """The whole chain in plain Python from a video file (the flow ``flows/video.py`` runs the same stages as
    cached tasks): shots by scenedetect (or the given ``cuts``), people from the ``perception`` spec
    (:func:`multithumbs.perception.load_perception`), camera trajectories and shared spaces by pycolmap with
    the people masked out, then :func:`run_video`. ``intrinsics`` ``(3, 3)``, when None, are estimated
    from the pixels (:func:`multithumbs.scene.focal.estimate_focal`: straight edges' vanishing points, else a
    moving camera, else people's heights, else a 60° horizontal field of view); the diagnostics
    ``focal_px``, ``focal_source`` and ``focal_detail`` say which. Decodes the whole video into memory: meant for clips.
    """
    from multithumbs.perception import load_perception
    from multithumbs.scene.focal import estimate_focal, frames_estimate, given_focal
    from multithumbs.scene.geometry import scene_geometry
    from multithumbs.scene.shots import detect_shots
    from multithumbs.scene.two_view import default_intrinsics
    from multithumbs.video import probe_video, read_frames

    info = probe_video(video_path)
    if cuts is None:
        shots = detect_shots(video_path)
    else:
        shots = Shots(np.asarray(cuts, np.int64), info.fps, info.num_frames, np.zeros(info.num_frames), "given")
    frames = read_frames(video_path)
    if intrinsics is None:  # the focal length from the pixels (multithumbs.scene.focal); perception needs a K first
        motion = frames_estimate(frames, shots.ranges)
        K = default_intrinsics(info.width, info.height) if motion[0] is None else motion[0].K(info.width, info.height)
    else:
        K = np.asarray(intrinsics, np.float64)
    tracks = load_perception(perception, video_path, shots, trust=trust_pickle, intrinsics=K, body=body)
    focal = given_focal(K) if intrinsics is not None else estimate_focal(frames, shots.ranges, tracks=tracks, from_frames=motion)
    K = K if intrinsics is not None else focal.K(info.width, info.height)  # tracks keep theirs: re-expressed
    geometry = scene_geometry(frames, shots, K, np.concatenate([tr.people_mask() for tr in tracks]))
    result = run_video(shots, tracks, list(geometry.trajectories), list(geometry.spaces), body, config)
    result.diagnostics.update(focal_px=np.float64(focal.focal_px), focal_source=np.str_(focal.source),
                              focal_detail=np.str_(focal.detail))
    return result
