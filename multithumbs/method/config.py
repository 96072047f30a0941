"""The method's settings: each stage's config, the whole method's, and its named variants.

Plain dataclasses, no torch: the flows compute a run's stage parameters (and so its artifact keys) from
them, and a re-run served from the store never imports the method (:mod:`tasks.method`). The stages'
modules re-export their own config (``multithumbs.method.align.AlignConfig`` and so on).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

from multithumbs.errors import InputError


@dataclass(frozen=True)
class AlignConfig:
    """Alignment settings (paper §3.2 defaults).

    Attributes:
        iterations: iterations of stages 1, 2 and 3 (stage 1 is the initialisation; its count is kept for
            the record, as in Algorithm 1, and costs nothing).
        lr_root: AdamW learning rate of the roots (m and rad per step).
        lr_camera: AdamW learning rate of the cameras.
        w2d_stage2: λ2D in stage 2.
        w2d_stage3: λ2D in stage 3.
        w_sil: λsil.
        w_depth: λdepth.
        refine_cameras: stage 3 also refines both cameras (False: the ``no_cam`` ablation).
        staged: run the stages in order (False: the ``no_stage`` ablation — every parameter from the
            estimator's own placement, optimised jointly under the full objective from the start).
        keypoint_confidence: 2D keypoints below this confidence are ignored.
        max_vertices: vertices per body used by the silhouette and depth losses (an even subsample).
        min_person_points: fewest scene points in a mask for a person to count in the scale estimate.
        depth_robust_scale: Geman-McClure scale (m) of the depth residual: vertices hidden behind another
            part of the same body (whose pixel shows that part) are outliers, not targets; 0 = plain squares.
            The kernel's pull fades beyond about this distance, so it must exceed the depth error left by a
            mesh whose size is a few percent off (0.15 m: standard suite full W-MPJPE 177.8 mm against 188.4
            with 0.05, which let the 2D term alone set each person's depth; 194.1 with plain squares).
        scale_method: ``"depth_ratio"`` (default: mesh over scene depth at the visible vertices' pixels) or
            ``"max_radius"`` (the paper's ratio of maximum centroid-to-vertex distances); both compare a
            mesh's size with its point cloud's, see :mod:`multithumbs.method.scale`.
        fit_scale_to_keypoints: for ``depth_ratio``, place each mesh at the depth where its joints
            reproject onto its 2D keypoints (:func:`fit_pelvis_to_keypoints`) before comparing depths, so
            the scale follows the meshes' metric size and not the estimator's depth, which monocular
            estimators get wrong by a per-track factor (False: the estimator's depth, as before).
        threads: torch intra-op threads of the alignment, its setup and optimisation loop, set for good with
            :func:`multithumbs.determinism.fix_threads` (0: leave torch's setting). The result's rounding
            depends on the count, so it is fixed, never toggled and restored (that raced across threads).
        points_follow_cameras: points observed in one boundary frame only move with that frame's camera
            in stage 3 (module docstring); False for point maps predicted in the world directly (VGGT's
            point head), which stay fixed while the cameras move, as in the paper.
        register_views: before the stages, correct the second boundary camera so both frames' static
            scenes agree (:func:`multithumbs.method.views.register_views`); part of the camera
            refinement, so off with ``refine_cameras=False``.
        view_samples: background points sampled per frame for that registration.
        view_robust_scale: its Cauchy scale and occlusion margin (m).
        view_smoothing_px: smoothing of the depth maps it compares with (pixels).
        people_cameras: when the boundary cameras come from the people seen on both sides of the cut
            (:mod:`multithumbs.method.people_cameras`): ``"fallback"`` (default: when the shared space has
            no cameras of its own, ``human_only`` or ``rotation_only``, and when its pose came from a
            fallback path, ``neighbour_frames`` or ``with_people``, that disagrees with the people's by more
            than ``people_agreement_deg``: at a reverse cut such a pose is often a spurious match),
            ``"always"`` or ``"never"``.
        people_agreement_deg: see ``people_cameras``.
        people_w_appearance: weight of the appearance dissimilarity in choosing who is who there.
        people_unmatched_cost: cost of leaving a person unmatched there (a matched pair costs its
            reprojection error in units of 5 % of the person's size, its orientation's disagreement in units
            of 10 degrees and its weighted appearance dissimilarity).
        max_depth_departure: largest departure of an aligned root's camera-frame depth from the
            estimator's, as a share of the estimator's. Beyond it, the scene points that moved the root
            were not on that person (pixel-derived point maps between the legs, or at a mask's edge, hold
            the wall behind or someone in front), and the root is put back where the estimator saw it,
            through the refined camera. Without this, a person moved 1.4 m nearer was carried along their
            whole shot and lost their identity at the cut before it (docs/RESULTS.md, session 16). 0.3 is
            2.6 standard deviations of a 4DHumans-class per-track depth error (10 %, the simulated
            perception's), so a right alignment is rarely undone. ``inf``: never.
        w_camera_prior: weight of ``‖ω‖² + ‖C − C₀‖²`` (rad², m²) keeping stage 3's cameras near their
            registered poses: with points that follow their cameras, the people's losses leave a gauge
            (camera, its points and its people moving together) that this fixes. It is also what keeps the
            people from dragging a camera the static scenes already registered: at 0.1 stage 3 left s08's
            second camera where the registration put it, at 1e-3 the people's depths moved it. Standard suite,
            full W-MPJPE at 1e-3 / 1e-2 / 0.1 / 1: simulated perception 101.4 / 100.7 / 100.7 / 100.7 mm; from
            the pixels 654.3 / 646.7 / 645.5 / 645.5 mm (s08's second camera was pulled 0.25 m off by
            BlazePose's fitted depths: 875 -> 799 mm; docs/RESULTS.md, session 27).
    """

    iterations: tuple[int, int, int] = (500, 500, 1500)
    lr_root: float = 0.01
    lr_camera: float = 0.002
    w2d_stage2: float = 10.0
    w2d_stage3: float = 50.0
    w_sil: float = 0.01
    w_depth: float = 1.0
    refine_cameras: bool = True
    staged: bool = True
    keypoint_confidence: float = 0.3
    max_vertices: int = 400
    min_person_points: int = 20
    depth_robust_scale: float = 0.15
    scale_method: str = "depth_ratio"
    fit_scale_to_keypoints: bool = True
    threads: int = 1
    points_follow_cameras: bool = True
    register_views: bool = True
    view_samples: int = 2000
    view_robust_scale: float = 0.3
    view_smoothing_px: float = 3.0
    w_camera_prior: float = 0.1
    people_cameras: str = "fallback"
    people_agreement_deg: float = 15.0
    people_w_appearance: float = 2.0
    people_unmatched_cost: float = 2.5
    max_depth_departure: float = 0.3


@dataclass(frozen=True)
class ReidConfig:
    """Re-identification weights and gates (paper §3.4 defaults).

    Attributes:
        w_geo: weight λgeo of the root distance D (per metre).
        w_app: weight λapp of the appearance dissimilarity A (in [0, 1]).
        w_pose: weight λpos of the pose dissimilarity P (mean joint angle, radians).
        max_distance: τ, matched pairs farther apart than this (m) are rejected.
        max_speed: when a candidate was last (or first) seen some time before (after) the cut, the gate
            grows by this walking speed times that gap (m/s): someone who left the view a second before
            the cut may be a metre away when they reappear.
        motion_window: seconds at the end of a person's observation over which the world root's velocity
            is fit (least squares, at most ``max_speed``); D is measured from the root carried by it over
            the time to the other side's observation, at most this long (no further than the fit's span),
            as a tracker predicts a lost track (0: from where they were last seen). Where both are seen
            at the cut nothing is carried: the paper's D.
        keypoint_confidence: a joint counts as visible when its 2D keypoint confidence exceeds this.
        link_gap: most seconds between the end of one track and the start of another in the same shot
            for the second to be linked to the first as the same person, on the same cost and distance gate
            as a cut (:func:`multithumbs.method.identities.link_fragments`; 0: never). A tracker loses
            people behind others and finds them again under a new id; 2 s is the CPU tracker's own horizon
            for finding a lost person again by appearance (``TrackerConfig.relink_missed``).
        link_appearance: largest appearance dissimilarity A of a link within a shot. On the standard
            suite's pixel tracks, fragments of one person gave 0.12-0.40 and of two people 0.51-0.92
            (docs/RESULTS.md, session 23); 0.5, A's value when no region is seen in both, passes.
    """

    w_geo: float = 1.0
    w_app: float = 0.2
    w_pose: float = 0.35
    max_distance: float = 1.0
    max_speed: float = 1.5
    motion_window: float = 1.0
    keypoint_confidence: float = 0.5
    link_gap: float = 2.0
    link_appearance: float = 0.5


@dataclass(frozen=True)
class PostConfig:
    """Post-processing settings (paper §3.5 defaults for λsmooth and λcross).

    Attributes:
        iterations: AdamW iterations.
        lr: learning rate (m or rad per step).
        w_smooth: λsmooth.
        w_cross: λcross.
        w_2d: weight of the per-frame 2D reprojection data term.
        w_root: weight of the prior keeping translations near their propagated values (m²).
        w_shape: weight of ‖β‖² inside the smoothness term.
        w_pose_prior: weight of the pose prior inside the smoothness term.

    The data and prior weights are set as a Gaussian MAP estimate would weigh them (each residual by
    ``1 / 2σ²``, relative to the 2D term): 2D keypoints good to ~2.5 px in a 640-px image (ViTPose-class;
    0.008 in normalised units), joint rotations good to ~6° (HMR2-class, 0.06 rad per axis-angle
    component) and a propagated root good to ~6 cm give ``w_pose_prior ≈ 0.0007`` and ``w_root ≈ 0.01``
    against ``w_2d = 10`` (about 24 keypoints per frame share it). The earlier ``w_pose_prior = 0.01``,
    ``w_root = 1`` held pose and roots ~10x and ~100x too firmly on the estimator's values; standard
    suite, full method: W-MPJPE 165.7 -> 154.3 mm, PA-MPJPE 20.5 -> 15.8 mm, Accel 7.57 -> 5.19
    (docs/RESULTS.md).
        pose_prior: ``"gaussian"`` (substitute, default) or ``"vposer"`` (needs ``vposer`` in :func:`post_process`).
        keypoint_confidence: keypoints below it are ignored.
        smooth_order: 1 penalises joint velocity ``‖J_t − J_{t+1}‖²`` (the paper's term); 2 penalises
            acceleration ``‖J_{t−1} − 2J_t + J_{t+1}‖²``, which leaves steady walking and the ends of a
            track alone (first differences pull a track's ends inwards and slow every walk).
        threads: torch intra-op threads of the optimisation loop, set for good (0: leave torch's setting);
            see :func:`multithumbs.determinism.fix_threads`.
        robust_sigma_px: Geman-McClure scale ``σ`` (px) of each keypoint's 2D residual in ``L_2D`` and
            ``L_cross``, ``ρ(r) = σ² r² / (σ² + r²)``: quadratic below it (ViTPose-class errors of a few
            pixels are unchanged), saturating above it, so a keypoint on the wrong limb or a reading
            mirrored front to back pulls with bounded force, as in the CPU backend's own fit
            (``BodyFitConfig.robust_sigma_px``). 0: plain squares.
    """

    iterations: int = 300
    lr: float = 0.01
    w_smooth: float = 10.0
    w_cross: float = 1.0
    w_2d: float = 10.0
    w_root: float = 0.01
    w_shape: float = 1e-5
    w_pose_prior: float = 0.001
    pose_prior: str = "gaussian"
    keypoint_confidence: float = 0.3
    smooth_order: int = 2
    threads: int = 1
    robust_sigma_px: float = 20.0


VARIANTS = ("full", "no_cam", "no_post", "no_stage", "no_align", "independent_shots", "appearance_only",
            "distance_only")


@dataclass(frozen=True)
class MethodConfig:
    """The whole method's settings (paper defaults).

    Attributes:
        align: scale and alignment (§3.1–3.2).
        reid: re-identification (§3.4).
        post: post-processing (§3.5).
        skip_align: the ``no_align`` ablation.
        skip_post: the ``no_post`` ablation.
        independent_shots: the single-shot baseline (no shared space; cross-cut links by appearance and pose).
        appearance_window: frames next to a cut whose appearance descriptors are averaged for re-ID.
        propagate_orientation: carry the boundary alignment's orientation correction along each shot (the
            paper's §3.3). Default False: the aligned position is carried and the estimator's per-frame
            camera-relative orientation kept, because one frame's fitted orientation is noisier than the
            estimator's (standard suite: W-MPJPE 247.5 -> 204.3 mm, MPJPE 36.4 -> 28.4 mm; docs/RESULTS.md).
        variant: name of the variant this config implements (for reports).
    """

    align: AlignConfig = field(default_factory=AlignConfig)
    reid: ReidConfig = field(default_factory=ReidConfig)
    post: PostConfig = field(default_factory=PostConfig)
    skip_align: bool = False
    skip_post: bool = False
    independent_shots: bool = False
    appearance_window: int = 15
    propagate_orientation: bool = False
    variant: str = "full"


def variant_config(variant: str, base: MethodConfig = MethodConfig()) -> MethodConfig:
    """The config of a named variant, derived from ``base``."""
    if variant not in VARIANTS:
        raise InputError(f"variant {variant!r}: unknown; choose from {', '.join(VARIANTS)}")
    rep = dataclasses.replace
    no_geo = rep(base.reid, w_geo=0.0, max_distance=float("inf"))
    changes = {
        "full": {},
        "no_cam": {"align": rep(base.align, refine_cameras=False)},
        "no_post": {"skip_post": True},
        "no_stage": {"align": rep(base.align, staged=False)},
        "no_align": {"skip_align": True},
        "independent_shots": {"independent_shots": True, "reid": rep(no_geo, w_app=1.0, w_pose=1.0)},
        "appearance_only": {"reid": rep(no_geo, w_app=1.0, w_pose=0.0)},
        "distance_only": {"reid": rep(base.reid, w_app=0.0, w_pose=0.0)},
    }[variant]
    return rep(base, variant=variant, **changes)
