"""The boundary cameras from the people themselves, when the scene cannot give them ("humans as a calibration
pattern"; the paper's related work).

At a reverse-angle cut (a dialogue's shot/reverse-shot, 120-180 degrees) the two boundary frames share
almost no background, and a shared space from the scene falls back to nothing. The people seen on both
sides of the cut are then the correspondence: one body seen from two cameras fixes the cameras' relative
pose (its orientation gives the rotation, its joints the translation, its metric size the scale), and the
keypoints of both views triangulate it across a wide baseline.

Which person on one side is which on the other is not known before re-identification. Every partial
matching of the people on the two sides is a hypothesis. For each, the relative rotation is the mean of
the matched bodies' relative orientations, and the translation and one pelvis per matched person are
fitted to the 2D keypoints of both views by robust least squares (``scipy.optimize.least_squares``,
soft-L1; :func:`fit_hypothesis`). Its cost is, per matched pair, the median reprojection error (in units
of ``reprojection_scale`` of the person's size in the image), the angle between the pair's own relative orientation and the
hypothesis's rotation (in ``orientation_scale_deg``) and ``w_appearance`` times the pair's appearance
dissimilarity; plus ``unmatched_cost`` for each person left unmatched (halved per side). Geometry cannot choose between two mirror hypotheses (the camera turned
around the people, or the people swapped places: both fit), so the appearance term decides among those;
geometry rejects the matchings no single camera motion explains.

Frames: camera 0 is the world (``R = I``, ``t = 0``); camera 1's pose ``X_1 = R X_0 + t``. Metres (the
meshes' metric size).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from multithumbs.appearance import appearance_dissimilarity
from multithumbs.geometry import axis_angle_to_matrix, project, rotation_angle


@dataclass(frozen=True)
class PeopleCameras:
    """Outcome of :func:`cameras_from_people`.

    Attributes:
        R: ``(2, 3, 3)`` world-to-camera rotations (camera 0 is the world).
        t: ``(2, 3)`` translations.
        pairs: ``(M, 2)`` int, matched (side-0 index, side-1 index) into the boundary people.
        roots: ``(M, 2, 3)`` each matched person's fitted world root: axis-angle orientation, pelvis.
        cost: the chosen hypothesis's cost (module docstring).
        reprojection: median reprojection error of the matched people's keypoints, both views, relative
            to each person's size in the image.
        hypotheses: how many matchings were tried.
        found: False when no hypothesis had a matched pair with enough keypoints (cameras left as given).
    """

    R: np.ndarray
    t: np.ndarray
    pairs: np.ndarray
    roots: np.ndarray
    cost: float
    reprojection: float
    hypotheses: int
    found: bool


def partial_matchings(n0: int, n1: int, max_pairs: int | None = None) -> list[tuple[tuple[int, int], ...]]:
    """Every non-empty injective matching between ``n0`` and ``n1`` items, as tuples of (i, j) pairs."""
    out = []
    top = min(n0, n1) if max_pairs is None else min(n0, n1, max_pairs)
    for m in range(1, top + 1):
        for left in itertools.combinations(range(n0), m):
            for right in itertools.permutations(range(n1), m):
                out.append(tuple(zip(left, right)))
    return out


def _camera_joints(local_joints: np.ndarray, orient: np.ndarray, pelvis: np.ndarray) -> np.ndarray:
    """``(..., 24, 3)`` joints placed by axis-angle ``orient (..., 3)`` at ``pelvis (..., 3)``."""
    return np.einsum("...ij,...kj->...ki", axis_angle_to_matrix(orient), local_joints) + pelvis[..., None, :]


def _initial_pose(orient: np.ndarray, joints: np.ndarray, pairs) -> tuple[np.ndarray, np.ndarray]:
    """Closed-form ``X_1 = R X_0 + t`` from the matched bodies: the mean relative orientation, the mean offset.

    ``orient (2, P, 3)`` camera-frame root orientations, ``joints (2, P, 24, 3)`` camera-frame joints.
    """
    body = [Rotation.from_rotvec(orient[k]) for k in range(2)]
    relative = Rotation.concatenate([body[1][j] * body[0][i].inv() for i, j in pairs]).mean()
    R = relative.as_matrix()
    t = np.mean([(joints[1, j] - joints[0, i] @ R.T).mean(axis=0) for i, j in pairs], axis=0)
    return R, t


def _extent(keypoints: np.ndarray, use: np.ndarray) -> float:
    """The larger side (px) of the box around the used keypoints ``(24, 3)``, at least 1."""
    xy = keypoints[use, :2]
    return float(max(np.ptp(xy, axis=0).max(), 1.0)) if len(xy) > 1 else 1.0


def fit_hypothesis(pairs, local_joints: np.ndarray, orient: np.ndarray, pelvis: np.ndarray,
                   keypoints: np.ndarray, K: np.ndarray, min_conf: float = 0.3, keypoint_sigma_px: float = 3.0,
                   depth_sigma: float = 0.1, robust_sigmas: float = 2.0
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Relative camera pose and the matched people's shared positions from both views.

    The rotation is the mean of the matched bodies' relative orientations (each body seen by both cameras
    turns with the camera). It is not refitted to the keypoints: a body is nearly flat, so a 2D fit of its
    orientation under a slightly wrong pose turns it by 10-20 degrees (measured on the dialogue scenes),
    where the estimator's orientations agree to 1-3. The translation and one pelvis per matched person are
    then fitted to the keypoints of both views (orientations fixed, each view's own), which triangulates
    them across the cut's wide baseline, with a prior on each view's keypoint-fitted depth.

    Args:
        pairs: ``(i, j)`` matched side-0 / side-1 people.
        local_joints: ``(2, P, 24, 3)`` posed joints relative to the pelvis, zero root orientation.
        orient, pelvis: ``(2, P, 3)`` the estimator's camera-frame roots (``pelvis`` at the keypoint-fitted
            depth, whose error is the body's size error).
        keypoints: ``(2, P, 24, 3)`` 2D keypoints with confidence.
        K: ``(2, 3, 3)``.
        keypoint_sigma_px, depth_sigma: the errors expected of the keypoints (px) and of the keypoint-fitted
            depths (relative): each residual is in units of its sigma, as a Gaussian MAP estimate weighs them.
        robust_sigmas: soft-L1 scale, in sigmas (occluded or mislabelled keypoints weigh less beyond it).
    Returns:
        ``R (3, 3)``, ``t (3,)`` of camera 1 (``X_1 = R X_0 + t``); ``(M, 2, 3)`` the shared roots (world
        axis-angle as camera 0 sees the body, pelvis); ``(M,)`` each pair's median reprojection error (px)
        over its confident keypoints in both views, relative to the person's size in the image (the larger
        extent of those keypoints); ``(M,)`` the angle (degrees) between each pair's own
        relative orientation and ``R`` (a pair that is not one person disagrees with the others).
    """
    pairs = list(pairs)
    m = len(pairs)
    joints = _camera_joints(local_joints, orient, pelvis)
    R, t0 = _initial_pose(orient, joints, pairs)
    use = keypoints[..., 2] >= min_conf
    weight = np.sqrt(np.clip(keypoints[..., 2], 0, 1))
    body = [axis_angle_to_matrix(orient[k]) for k in range(2)]                  # (P, 3, 3) camera-frame
    placed_local = [[local_joints[0, i] @ body[0][i].T, local_joints[1, j] @ (R.T @ body[1][j]).T]
                    for i, j in pairs]                                          # world-frame joint offsets
    start = np.concatenate([np.zeros(3), *[pelvis[0, i] for i, _ in pairs]])
    # A person's size in the image: the extent of their confident keypoints (the error's unit, as PCK's).
    size = [{p: _extent(keypoints[k, p], use[k, p]) for p in {pair[k] for pair in pairs}} for k in range(2)]

    def residuals(x, report=False):
        t = x[:3] + t0
        out, errors = [], []
        for n, (i, j) in enumerate(pairs):
            root = x[3 + 3 * n:6 + 3 * n]
            for k, p in ((0, i), (1, j)):
                placed = placed_local[n][k] + root
                if k == 1:
                    placed = placed @ R.T + t
                diff = (project(placed, K[k]) - keypoints[k, p, :, :2]) * use[k, p, :, None]
                errors.append(np.linalg.norm(diff, axis=1)[use[k, p]] / size[k][p])
                out.append((diff * weight[k, p, :, None]).ravel() / keypoint_sigma_px)
                depth = max(float((root if k == 0 else root @ R.T + t)[2]), 1e-3)
                out.append(np.array([np.log(depth / max(pelvis[k, p, 2], 1e-3)) / depth_sigma]))
        if report:
            return [float(np.median(np.concatenate(errors[2 * n:2 * n + 2]))) if
                    sum(len(e) for e in errors[2 * n:2 * n + 2]) else np.inf for n in range(m)]
        return np.concatenate(out)

    fit = least_squares(residuals, start, loss="soft_l1", f_scale=robust_sigmas, x_scale="jac", max_nfev=200)
    x = fit.x if np.all(np.isfinite(fit.x)) else start
    roots = np.stack([np.stack([orient[0, i], x[3 + 3 * n:6 + 3 * n]]) for n, (i, _) in enumerate(pairs)])
    disagreement = np.array([np.rad2deg(rotation_angle(body[1][j] @ body[0][i].T, R)) for i, j in pairs])
    return R, x[:3] + t0, roots, np.asarray(residuals(x, report=True)), disagreement


def cameras_from_people(people, pelvis_cam: np.ndarray, K: np.ndarray, min_conf: float = 0.3,
                        min_keypoints: int = 8, w_appearance: float = 2.0, unmatched_cost: float = 2.5,
                        reprojection_scale: float = 0.05, orientation_scale_deg: float = 10.0,
                        max_pairs: int = 3) -> PeopleCameras:
    """The boundary cameras from the people seen on both sides of a cut (module docstring).

    Args:
        people: :class:`multithumbs.method.align.BoundaryPeople` (with ``appearance`` when known).
        pelvis_cam: ``(2, P, 3)`` camera-frame pelvis at the keypoint-fitted depth.
        K: ``(2, 3, 3)``.
        min_keypoints: a person takes part with at least this many confident keypoints.
        reprojection_scale, orientation_scale_deg: units, in the cost, of a pair's reprojection error
            (relative to the person's size in the image) and of its orientation's disagreement with the
            hypothesis's rotation (module docstring).
        max_pairs: matchings of at most this many pairs are tried (the count grows factorially).
    """
    usable = [[p for p in np.nonzero(people.present[k])[0]
               if (people.keypoints[k, p, :, 2] >= min_conf).sum() >= min_keypoints] for k in range(2)]
    eye = np.stack([np.eye(3)] * 2)
    none = PeopleCameras(eye, np.zeros((2, 3)), np.zeros((0, 2), np.int64), np.zeros((0, 2, 3)), float("inf"),
                         float("nan"), 0, False)
    if not usable[0] or not usable[1]:
        return none
    appearance = getattr(people, "appearance", None)
    if appearance is not None:
        dissimilar = appearance_dissimilarity(appearance[0][:, None], appearance[1][None])
    else:
        dissimilar = np.full((people.present.shape[1],) * 2, 0.5)
    best = None
    hypotheses = partial_matchings(len(usable[0]), len(usable[1]), max_pairs)
    for hypothesis in hypotheses:
        pairs = [(usable[0][a], usable[1][b]) for a, b in hypothesis]
        R, t, roots, errors, turned = fit_hypothesis(pairs, people.local_joints, people.orient_cam, pelvis_cam,
                                                     people.keypoints, K, min_conf)
        pair_cost = errors / reprojection_scale + turned / orientation_scale_deg + \
            w_appearance * np.array([dissimilar[i, j] for i, j in pairs])
        unmatched = 0.5 * (len(usable[0]) + len(usable[1]) - 2 * len(pairs))
        cost = float(pair_cost.sum() + unmatched_cost * unmatched)
        # Ties (mirror hypotheses of look-alikes) go to the first tried: the order is fixed, so is the result.
        if best is None or cost < best[0] - 1e-12:
            best = (cost, R, t, pairs, roots, float(np.median(errors)))
    cost, R, t, pairs, roots, reprojection = best
    return PeopleCameras(np.stack([np.eye(3), R]), np.stack([np.zeros(3), t]), np.asarray(pairs, np.int64),
                         roots, cost, reprojection, len(hypotheses), True)
