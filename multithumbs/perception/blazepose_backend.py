"""People from the pixels on CPU: BlazePose tracks and SMPL bodies fitted to them, per shot.

The ``blazepose`` perception source (the default of ``multithumbs run``). For each shot:

1. :func:`multithumbs.perception.pose_tracking.track_shot` finds and follows the people with BlazePose's
   detector and landmark model (:mod:`.blazepose`, weights from MediaPipe's wheel, :mod:`.blazepose_models`);
2. the 33 landmarks become SMPL-order 2D keypoints with BlazePose's visibility as confidence, and its
   world landmarks the matching 3D joints (:func:`multithumbs.perception.joints.blazepose33_to_smpl24`);
3. :func:`multithumbs.perception.body_fit.fit_bodies` fits the body model to both in the scene's
   intrinsics, batched over the shot's people and frames;
4. a reading whose hips and shoulders face opposite ways has its hips and legs mirrored onto the
   shoulders' side; each track's readings are labelled front or back by where the fitted root walks,
   whether the head shows a face or hair (:mod:`.head_colour`) and how slowly bodies turn; the frames
   taken for BlazePose's front/back confusion are mirrored, every walker's reading is turned about its
   trunk towards the walk, and the shot is fitted again (:mod:`.facing`); the walk is read with the
   camera's own motion taken out, as the floor at each person's feet shows it (:mod:`.ground_motion`);
5. short tracks whose feet are off the floor the shot's other people stand on are dropped: BlazePose
   read a pattern (a rug, the torso of someone close to the camera) as a person (:mod:`.floor_check`);
6. short gaps inside a track are bridged by the body between the readings on either side (:mod:`.gap_fill`).

Masks come from BlazePose's segmentation. Appearance is described afterwards from the pixels, as for every
source (:mod:`.appearance`). A gap of a few frames inside a track is bridged by the body between the
readings around it, with no keypoint confidence there (:mod:`.gap_fill`); other frames where a person was
not followed stay invalid.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Iterable

import numpy as np

from multithumbs.appearance import DESCRIPTOR_SIZE
from multithumbs.errors import InputError
from multithumbs.perception.body_fit import BodyFitConfig, FittedBodies, fit_bodies
from multithumbs.perception.facing import (HIP_LANDMARKS, SHOULDER_LANDMARKS, FacingConfig, body_seen, facing_flips,
                                           landmarks_seen, mirrored, root_velocity, untwisted, walk_headings)
from multithumbs.perception.floor_check import FloorCheckConfig, drop_off_floor
from multithumbs.perception.gap_fill import GapFillConfig, bridge_gaps
from multithumbs.perception.ground_motion import GroundMotionConfig, ground_flow, static_velocity
from multithumbs.perception.head_colour import HeadColourConfig, face_evidence, head_samples
from multithumbs.perception.joints import blazepose33_to_smpl24
from multithumbs.perception.pose_tracking import ShotPoses, TrackerConfig, track_shot
from multithumbs.types import PersonTracks, Shots

@dataclass(frozen=True)
class BlazePoseConfig:
    """The CPU backend's settings."""

    tracker: TrackerConfig = field(default_factory=TrackerConfig)
    """How people are found and followed within a shot."""
    fit: BodyFitConfig = field(default_factory=lambda: BodyFitConfig(w_joints3d=25.0))
    """How bodies are fitted to the landmarks. BlazePose's world landmarks are off by ~10 cm per joint
    after Procrustes on the suite's people (``benchmarks/cpu_perception.py``), so the 3D term is trusted
    to σ = 20 cm (weight 1/σ²), not the 5 cm of :class:`BodyFitConfig`'s default."""
    facing: FacingConfig = field(default_factory=FacingConfig)
    """When a reading is taken for a back seen as a front and mirrored (PCK 0.841 -> see docs/RESULTS.md)."""
    ground: GroundMotionConfig = field(default_factory=GroundMotionConfig)
    """How the camera's own motion is read from the floor at each person's feet for the facing's walk."""
    head: HeadColourConfig = field(default_factory=HeadColourConfig)
    """How the facing reads a face or the back of a head from the head's colours (:mod:`.head_colour`)."""
    floor: FloorCheckConfig = field(default_factory=FloorCheckConfig)
    """Which short tracks are dropped for feet off the shot's floor (:mod:`.floor_check`)."""
    gaps: GapFillConfig = field(default_factory=GapFillConfig)
    """Which gaps inside a track are bridged by the body between the readings around them (:mod:`.gap_fill`)."""
    num_threads: int = 2
    """Threads of each tflite interpreter."""
    person_detector: str = "nanodet"
    """Where the tracker's proposals come from (``tracker.proposals``): ``"nanodet"``, the COCO detector of
    :mod:`.nanodet`, which sees people from behind and half hidden; ``"hog"``, OpenCV's pedestrian detector."""
    person_min_score: float = 0.35
    """NanoDet person score from which a box is a proposal."""


@dataclass(frozen=True)
class StageSeconds:
    """Where the backend's time went, summed over shots (wall seconds)."""

    landmarks: float
    """BlazePose's detector and landmark models with their pre- and post-processing, and the tracking (the
    person detector's own time is :attr:`detection`; HOG's, when it is the one, is counted here)."""
    detection: float
    """The whole-body person detector (NanoDet) whose boxes are the tracker's proposals."""
    fitting: float
    """Body fitting, with the floor's shift at the feet and the facing labelling."""
    detector_calls: int
    """Detector invocations."""
    landmark_calls: int
    """Landmark model invocations."""
    frames: int
    """Frames processed."""


def _fit(image: np.ndarray, world: np.ndarray, valid: np.ndarray, K: np.ndarray, body,
         config: BodyFitConfig) -> tuple[np.ndarray, FittedBodies]:
    """SMPL-order keypoints of BlazePose's landmarks and the bodies fitted to them (steps 2–3)."""
    visibility = image[..., 3:4]
    keypoints = blazepose33_to_smpl24(np.concatenate([image[..., :2], visibility], axis=-1))
    joints3d = blazepose33_to_smpl24(np.concatenate([world, visibility], axis=-1))
    keypoints = np.where(valid[..., None, None], keypoints, 0.0)
    joints3d = np.where(valid[..., None, None], joints3d, 0.0)
    return keypoints, fit_bodies(keypoints, joints3d, valid, K, body, config)


def read_walk(poses: ShotPoses, fitted: FittedBodies, config: FacingConfig, K: np.ndarray | None = None,
              floor_flow: np.ndarray | None = None, image_size: tuple[int, int] | None = None
              ) -> tuple[np.ndarray, np.ndarray]:
    """The walk ``(P, T, 3)`` (the first fit's root motion per frame over every valid frame, less the motion
    of a static point there when the floor's shift ``floor_flow (P, T, 2)``,
    :func:`.ground_motion.ground_flow`, and ``K`` are given) and the ``(P, T)`` frames it judges
    (:func:`.facing.body_seen`, inside the image when its ``(H, W)`` is given)."""
    judged = body_seen(poses.image, config.min_leg_visibility, image_size)
    walk = root_velocity(fitted.transl, poses.valid, config.window)
    if floor_flow is not None and K is not None:
        walk = walk - static_velocity(floor_flow, fitted.transl, poses.valid, K, config.window)
    return walk, judged


def mirror_flips(poses: ShotPoses, walk: np.ndarray, judged: np.ndarray, config: FacingConfig,
                 face: np.ndarray | None = None, view: np.ndarray | None = None) -> np.ndarray:
    """``(P, T)`` bool: frames whose reading the walk (:func:`read_walk`, seen along ``view``,
    :func:`view_directions`), the head's colours ``face`` (:func:`shot_face_evidence`) and the turns take
    for a back seen as a front (step 4)."""
    if not config.enabled or not poses.valid.any():
        return np.zeros(poses.valid.shape, bool)
    hips = landmarks_seen(poses.image, config.min_hip_visibility, HIP_LANDMARKS)
    if config.link_shoulders:
        linked = poses.valid & (hips | landmarks_seen(poses.image, config.min_hip_visibility, SHOULDER_LANDMARKS))
    else:
        linked = poses.valid & hips
    return facing_flips(poses.world, walk, linked, judged, config, face, hips, view)


def view_directions(transl: np.ndarray) -> np.ndarray:
    """``(P, T, 3)`` unit vectors from the camera to the fitted roots ``transl (P, T, 3)`` (camera frame)."""
    transl = np.asarray(transl, dtype=np.float64)
    return transl / np.maximum(np.linalg.norm(transl, axis=-1, keepdims=True), 1e-12)


def shot_floor_flow(frames, poses: ShotPoses, config: BlazePoseConfig) -> np.ndarray | None:
    """The floor's shift at each person's feet in a shot's frames (:func:`.ground_motion.ground_flow`), or
    None when the facing labelling or the floor reading is off."""
    if not (config.facing.enabled and config.ground.enabled):
        return None
    return ground_flow(frames, poses.image, poses.boxes, poses.masks, poses.valid, config.ground)


def shot_face_evidence(frames, poses: ShotPoses, config: BlazePoseConfig) -> np.ndarray | None:
    """``(P, T)`` in [-1, 1]: where each person's head shows a face (+1) or its back (-1) in a shot's frames
    (:func:`.head_colour.face_evidence`), or None when the facing labelling or the cue is off."""
    if not (config.facing.enabled and config.head.enabled):
        return None
    return face_evidence(head_samples(frames, poses.image, poses.masks, poses.valid, config.head), config.head)


def poses_to_tracks(poses: ShotPoses, shot_index: int, start_frame: int, K: np.ndarray, image_size: tuple[int, int],
                    body=None, config: BodyFitConfig | None = None,
                    facing: FacingConfig = FacingConfig(), floor_flow: np.ndarray | None = None,
                    face: np.ndarray | None = None, floor: FloorCheckConfig = FloorCheckConfig(),
                    gaps: GapFillConfig = GapFillConfig()) -> PersonTracks:
    """One shot's :class:`PersonTracks` from the people BlazePose followed (module docstring, steps 2–6);
    ``floor_flow (P, T, 2)``, when given, is the floor's shift at each person's feet
    (:func:`.ground_motion.ground_flow`), which takes the camera's motion out of the walk; ``face (P, T)``,
    when given, is where each head shows a face or its back (:func:`shot_face_evidence`). Tracks of no one
    are dropped (``floor``), then short gaps in the others bridged (``gaps``)."""
    p, t = poses.valid.shape
    h, w = image_size
    if body is None:
        from multithumbs.body.model import load_body_model

        body = load_body_model()
    config = config or BlazePoseConfig().fit
    image, world, twists = untwisted(poses.image, poses.world, poses.valid, facing)
    if twists.any():
        poses = replace(poses, image=image, world=world)
    keypoints, fitted = _fit(poses.image, poses.world, poses.valid, K, body, config)
    walk, judged = read_walk(poses, fitted, facing, K, floor_flow, image_size)
    # The head's colours, like the walk, count on whole bodies only: on Megamind.avi's close-ups the crown,
    # placed by the neck's length, fell on foreheads and the cue relabelled 29 of 422 person-frames.
    view = view_directions(fitted.transl)
    flips = mirror_flips(poses, walk, judged, facing, None if face is None else np.where(judged, face, 0.0), view)
    image, world = mirrored(poses.image, poses.world, flips)
    world, turns = walk_headings(world, walk, judged & poses.valid, facing, view)
    if flips.any() or turns.any():
        keypoints, fitted = _fit(image, world, poses.valid, K, body, config)
    return bridge_gaps(drop_off_floor(PersonTracks(
        shot_index=shot_index, start_frame=start_frame, track_ids=poses.track_ids,
        global_orient=fitted.global_orient, body_pose=fitted.body_pose, betas=fitted.betas, transl=fitted.transl,
        keypoints2d=keypoints, masks=poses.masks if p else np.zeros((0, t, h, (w + 7) // 8), np.uint8),
        image_size=(h, w), K=np.asarray(K, np.float64), appearance=np.zeros((p, t, DESCRIPTOR_SIZE)),
        appearance_valid=np.zeros((p, t), bool), valid=poses.valid), floor), body, gaps)


def person_proposals(config: BlazePoseConfig, detector=None, seconds: dict | None = None):
    """The tracker's ``people`` proposals for ``config`` (None: HOG's, or none), loading NanoDet unless
    ``detector`` is given; the time it takes is added to ``seconds["detection"]`` when given."""
    if not config.tracker.proposals or config.person_detector == "hog":
        return None
    if config.person_detector != "nanodet":
        raise InputError(f"person detector {config.person_detector!r}: unknown; known: nanodet, hog")
    if detector is None:
        from multithumbs.perception.nanodet import NanoDet

        detector = NanoDet()

    def people(frame: np.ndarray) -> np.ndarray:
        start = time.perf_counter()
        boxes = detector.people(frame, config.person_min_score)
        if seconds is not None:
            seconds["detection"] = seconds.get("detection", 0.0) + time.perf_counter() - start
        return boxes

    return people


def blazepose_tracks(frames: Iterable[np.ndarray], shots: Shots, K: np.ndarray, body=None,
                     config: BlazePoseConfig = BlazePoseConfig(), model=None, progress=None
                     ) -> tuple[list[PersonTracks], StageSeconds]:
    """Per-shot :class:`PersonTracks` of a video's frames (module docstring) and the time each stage took.

    Args:
        frames: the video's ``(H, W, 3)`` uint8 RGB frames in order (an iterator is read once).
        shots: its shots; tracking restarts at every cut, so ids never span one.
        K: ``(3, 3)`` intrinsics the bodies are fitted in.
        body: the body model (default :func:`multithumbs.body.model.load_body_model`).
        model: a loaded :class:`~multithumbs.perception.blazepose_models.BlazePose` (default: loaded here).
        progress: optional ``callable(shot_index, done_frames, shot_frames)``.
    """
    if model is None:
        from multithumbs.perception.blazepose_models import BlazePose

        model = BlazePose(num_threads=config.num_threads)
    if body is None:
        from multithumbs.body.model import load_body_model

        body = load_body_model()
    seconds = {"landmarks": 0.0, "detection": 0.0, "fitting": 0.0}
    people = person_proposals(config, seconds=seconds)
    iterator = iter(frames)
    out: list[PersonTracks] = []
    calls = {"detector": 0, "landmark": 0}
    image_size = None
    for k, (a, b) in enumerate(shots.ranges):
        shot_frames = []
        for _ in range(b - a):
            frame = next(iterator, None)
            if frame is None:
                break
            shot_frames.append(frame)
            image_size = frame.shape[:2]
        report = (lambda done, _total, k=k, n=b - a: progress(k, done, n)) if progress else None
        start = time.perf_counter()
        detected = seconds["detection"]
        poses = track_shot(shot_frames, model, config.tracker, progress=report, people=people)
        seconds["landmarks"] += time.perf_counter() - start - (seconds["detection"] - detected)
        calls["detector"] += poses.detector_calls
        calls["landmark"] += poses.landmark_calls
        start = time.perf_counter()
        floor_flow = shot_floor_flow(shot_frames, poses, config)
        face = shot_face_evidence(shot_frames, poses, config)
        out.append(poses_to_tracks(poses, k, a, K, image_size, body, config.fit, config.facing, floor_flow, face,
                                   config.floor, config.gaps))
        seconds["fitting"] += time.perf_counter() - start
    return out, StageSeconds(seconds["landmarks"], seconds["detection"], seconds["fitting"], calls["detector"],
                             calls["landmark"], shots.num_frames)


def run_blazepose(video: str | Path, shots: Shots, K: np.ndarray, body=None,
                  config: BlazePoseConfig = BlazePoseConfig(), progress=None) -> list[PersonTracks]:
    """:func:`blazepose_tracks` on a video file."""
    from multithumbs.perception.blazepose_models import BlazePose
    from multithumbs.video import iter_frames

    tracks, _ = blazepose_tracks(iter_frames(video), shots, K, body, config,
                                 BlazePose(num_threads=config.num_threads), progress)
    return tracks


__all__ = ["BlazePoseConfig", "StageSeconds", "shot_floor_flow", "shot_face_evidence", "poses_to_tracks",
           "blazepose_tracks", "run_blazepose"]
