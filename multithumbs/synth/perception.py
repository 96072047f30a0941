"""Simulated per-shot perception: ground truth corrupted the way real estimators fail (DESIGN §7).

This stands in for 4DHumans/PHALP + ViTPose + SAM on synthetic scenes. From the truth it takes only
what those tools estimate (each person's SMPL in the shot's camera frame, 2D joints, masks) and corrupts
it: per-frame pose jitter plus a slowly drifting pose bias, a per-track depth scale error and per-frame
depth jitter along the viewing ray (monocular depth is ambiguous; the 2D projection is kept), noisy
shape, missed detections, keypoint noise and dropout, eroded masks, and local ids shuffled per shot.
Appearance descriptors are computed from the rendered pixels inside the masks, never from truth.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy.ndimage import gaussian_filter1d
from scipy.spatial.transform import Rotation

from multithumbs.appearance import DESCRIPTOR_SIZE, REGION_SIZE, describe_person
from multithumbs.body.model import BodyModel
from multithumbs.geometry import world_to_camera
from multithumbs.synth.scene import SyntheticVideo
from multithumbs.types import PersonTracks, pack_mask


@dataclass(frozen=True)
class PerceptionNoise:
    """How simulated perception fails. Defaults follow what 4DHumans-class estimators show on real video.

    Attributes:
        pose_jitter_deg: per-frame, per-joint rotation noise (degrees, std of the rotation angle).
        pose_bias_deg: slowly varying per-joint pose error (degrees), correlated over ``bias_seconds``.
        bias_seconds: correlation time of the slow errors (s).
        orient_jitter_deg: per-frame root orientation noise in the camera frame (degrees).
        betas_sigma: per-track shape error (std per coefficient).
        depth_scale_sigma: per-track multiplicative depth error (std of log scale) of the camera-frame position.
        depth_jitter: per-frame relative depth noise (std, fraction of depth), smoothed over a few frames.
        miss_rate: probability that a visible person is missed in a frame.
        min_visible_pixels: a person with fewer visible pixels is not detected.
        keypoint_sigma_px: 2D keypoint noise (pixels, std) of visible joints.
        occluded_keypoint_sigma_px: noise of joints the detector cannot see (pixels).
        keypoint_dropout: probability that a keypoint's confidence drops to zero.
        mask_erosion_px: masks are eroded by this many pixels (segmenters miss thin boundaries).
        shuffle_ids: local track ids are random and unrelated across shots.
    """

    pose_jitter_deg: float = 3.0
    pose_bias_deg: float = 5.0
    bias_seconds: float = 1.0
    orient_jitter_deg: float = 2.0
    betas_sigma: float = 0.3
    depth_scale_sigma: float = 0.1
    depth_jitter: float = 0.02
    miss_rate: float = 0.03
    min_visible_pixels: int = 150
    keypoint_sigma_px: float = 2.5
    occluded_keypoint_sigma_px: float = 12.0
    keypoint_dropout: float = 0.05
    mask_erosion_px: int = 1
    shuffle_ids: bool = True


NO_NOISE = PerceptionNoise(pose_jitter_deg=0, pose_bias_deg=0, orient_jitter_deg=0, betas_sigma=0,
                           depth_scale_sigma=0, depth_jitter=0, miss_rate=0, keypoint_sigma_px=0,
                           occluded_keypoint_sigma_px=0, keypoint_dropout=0, mask_erosion_px=0, shuffle_ids=False)
"""Perfect perception (for tests of the later stages): truth in each shot's camera frame."""


def _rotation_noise(rng: np.random.Generator, shape: tuple[int, ...], sigma_deg: float,
                    smooth_frames: float = 0.0, time_axis: int = 0) -> np.ndarray:
    """Random rotation vectors ``(*shape, 3)`` with angle std ``sigma_deg``, optionally smooth in time."""
    noise = rng.standard_normal((*shape, 3))
    if smooth_frames > 0:
        noise = gaussian_filter1d(noise, smooth_frames, axis=time_axis, mode="nearest")
        noise /= max(noise.std(), 1e-9)
    return noise * np.deg2rad(sigma_deg) / np.sqrt(3)


def _compose(rotvec_noise: np.ndarray, rotvec: np.ndarray) -> np.ndarray:
    shape = rotvec.shape
    out = Rotation.from_rotvec(rotvec_noise.reshape(-1, 3)) * Rotation.from_rotvec(rotvec.reshape(-1, 3))
    return out.as_rotvec().reshape(shape)


def simulate_perception(video: SyntheticVideo, body: BodyModel, noise: PerceptionNoise = PerceptionNoise(),
                        seed: int = 0) -> list[PersonTracks]:
    """Per-shot :class:`PersonTracks` of a synthetic video as an imperfect estimator would report them."""
    truth = video.truth
    world = truth.world
    rng = np.random.default_rng([video.scene.config.seed, seed, 7])
    h, w = world.image_size
    edges = [0, *world.cut_frames.tolist(), world.num_frames]
    pelvis_rest = body.rest_pelvis(world.betas)  # (P, 3) rotation centre of SMPL
    tracks = []
    for shot, (a, b) in enumerate(zip(edges[:-1], edges[1:])):
        frames = np.arange(a, b)
        counts = np.stack([(video.instance[a:b] == q).reshape(b - a, -1).sum(1) for q in range(world.num_people)])
        detected = truth.visible[:, a:b] & (counts >= noise.min_visible_pixels)
        detected &= rng.random(detected.shape) >= noise.miss_rate
        people = np.nonzero(detected.sum(1) >= 2)[0]  # a track needs at least two detections
        tracks.append(_shot_tracks(video, body, noise, rng, shot, frames, people, detected[people],
                                   pelvis_rest[people]))
    return tracks


def _shot_tracks(video: SyntheticVideo, body: BodyModel, noise: PerceptionNoise, rng: np.random.Generator,
                 shot: int, frames: np.ndarray, people: np.ndarray, detected: np.ndarray,
                 pelvis_rest: np.ndarray) -> PersonTracks:
    world = video.truth.world
    h, w = world.image_size
    p_count, t_count = len(people), len(frames)
    R, t, K = world.R[frames], world.t[frames], world.K[frames[0]]
    fps = world.fps
    bias_frames = noise.bias_seconds * fps

    # Root in the camera frame: orientation R @ orient; pelvis moves with the camera, transl follows.
    orient_w = world.global_orient[people][:, frames]
    orient_c = Rotation.from_matrix(np.einsum("tij,ptjk->ptik", R, Rotation.from_rotvec(
        orient_w.reshape(-1, 3)).as_matrix().reshape(p_count, t_count, 3, 3)).reshape(-1, 3, 3)).as_rotvec()
    orient_c = orient_c.reshape(p_count, t_count, 3)
    pelvis_w = world.transl[people][:, frames] + pelvis_rest[:, None]
    pelvis_c = world_to_camera(pelvis_w[:, :, None], R[None], t[None])[:, :, 0]

    # Corrupt: depth along the ray (keeps the 2D position), pose, orientation, shape.
    scale = np.exp(rng.normal(0, noise.depth_scale_sigma, (p_count, 1, 1)))
    jitter = 1 + gaussian_filter1d(rng.normal(0, noise.depth_jitter, (p_count, t_count)), 1.5, axis=1)[..., None]
    pelvis_c = pelvis_c * scale * jitter
    body_pose = world.body_pose[people][:, frames]
    body_pose = _compose(_rotation_noise(rng, body_pose.shape[:-1], noise.pose_jitter_deg), body_pose)
    bias = _rotation_noise(rng, (p_count, t_count, 23), noise.pose_bias_deg, bias_frames, time_axis=1)
    body_pose = _compose(bias, body_pose)
    orient_c = _compose(_rotation_noise(rng, orient_c.shape[:-1], noise.orient_jitter_deg), orient_c)
    betas = world.betas[people] + rng.normal(0, noise.betas_sigma, (p_count, 10))
    noisy_pelvis_rest = body.rest_pelvis(betas)
    transl_c = pelvis_c - noisy_pelvis_rest[:, None]

    # 2D keypoints: true projections with noise; occluded joints get large noise and low confidence.
    kp_true = world.keypoints2d[people][:, frames]
    seen = kp_true[..., 2] > 0.5
    sigma = np.where(seen, noise.keypoint_sigma_px, noise.occluded_keypoint_sigma_px)[..., None]
    uv = kp_true[..., :2] + rng.standard_normal(kp_true[..., :2].shape) * sigma
    conf = np.where(seen, rng.uniform(0.7, 1.0, seen.shape), rng.uniform(0.05, 0.4, seen.shape))
    conf[rng.random(conf.shape) < noise.keypoint_dropout] = 0.0
    keypoints = np.concatenate([uv, conf[..., None]], axis=-1)

    masks = np.zeros((p_count, t_count, h, (w + 7) // 8), np.uint8)
    appearance = np.zeros((p_count, t_count, DESCRIPTOR_SIZE))
    appearance_valid = np.zeros((p_count, t_count), bool)
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * noise.mask_erosion_px + 1,) * 2)
    for i, person in enumerate(people):
        for j in np.nonzero(detected[i])[0]:
            f = frames[j]
            mask = (video.instance[f] == person).astype(np.uint8)
            if noise.mask_erosion_px:
                mask = cv2.erode(mask, kernel)
            mask = mask.astype(bool)
            masks[i, j] = pack_mask(mask)
            appearance[i, j] = describe_person(video.frames[f], mask, keypoints[i, j])
            appearance_valid[i, j] = appearance[i, j, ::REGION_SIZE].any()  # any region valid

    ids = rng.choice(1000, size=p_count, replace=False) if noise.shuffle_ids else people.copy()
    order = rng.permutation(p_count) if noise.shuffle_ids else np.arange(p_count)
    valid = detected.astype(bool)
    zero_missing = lambda x: np.where(valid.reshape(valid.shape + (1,) * (x.ndim - 2)), x, 0.0)
    return PersonTracks(
        shot_index=shot, start_frame=int(frames[0]), track_ids=ids[order].astype(np.int64),
        global_orient=zero_missing(orient_c)[order], body_pose=zero_missing(body_pose)[order],
        betas=betas[order], transl=zero_missing(transl_c)[order], keypoints2d=zero_missing(keypoints)[order],
        masks=masks[order], image_size=(h, w), K=K, appearance=appearance[order],
        appearance_valid=appearance_valid[order], valid=valid[order],
    )


def true_track_people(tracks: PersonTracks, video: SyntheticVideo) -> np.ndarray:
    """``(P,)`` the true person index of every track (by mask overlap), -1 where none; for tests and benchmarks."""
    out = np.full(tracks.num_people, -1)
    for i in range(tracks.num_people):
        j = int(np.argmax(tracks.valid[i]))
        mask = tracks.mask(i, j)
        labels = video.instance[tracks.start_frame + j][mask]
        labels = labels[labels >= 0]
        if labels.size:
            out[i] = np.bincount(labels).argmax()
    return out
