"""Real per-shot perception (DESIGN §1 stage 2): the people of each shot as :class:`PersonTracks`.

``load_perception(spec, video_path, shots, trust=False)`` reads or computes them. The spec names a track
source and optional refiners, joined by ``+``::

    SPEC     := SOURCE ( "+" REFINER )*
    SOURCE   := "blazepose"                      BlazePose on CPU with bodies fitted to its landmarks
                                                 (:mod:`.blazepose_backend`; the default of ``run``)
              | "phalp:" PATH                    4DHumans/PHALP results (.pkl, joblib); needs trust=True
              | "hmr2" [ ":" OPTIONS ]           HMR2 on the video (the hmr2 package);
                                                 OPTIONS: checkpoint=PATH,detector=PATH
              | "oracle:" PATH                   exact tracks from a ground-truth .npz (:mod:`.oracle`:
                                                 for datasets without estimator output; not a method result)
    REFINER  := "vitpose" [ ":" MODEL ]          2D keypoints with ViTPose in the tracks' boxes
              | "sam" [ ":" MODEL ]              masks with SAM prompted by the tracks' boxes
    MODEL    := a local folder (save_pretrained) or a hub name already in the Hugging Face cache;
                defaults usyd-community/vitpose-base-simple and facebook/sam-vit-base

Examples: ``blazepose``, ``blazepose+sam``, ``phalp:results/demo_video.pkl``, ``hmr2:detector=/models/vitdet.pkl``,
``phalp:out.pkl+vitpose+sam:/models/sam-vit-base``. ``+`` separates terms, so paths cannot contain it.
After the source and refiners, appearance is described from the video's pixels
(:mod:`multithumbs.perception.appearance`, PHALP's ``appe`` codes vet it). Nothing is downloaded.

Modules: :mod:`.blazepose_backend` (the CPU source: :mod:`.blazepose`, :mod:`.blazepose_models`,
:mod:`.pose_tracking`, :mod:`.body_fit`), :mod:`.phalp` (import/export of PHALP results), :mod:`.camera` (HMR2's camera model),
:mod:`.joints` (COCO-17 / OpenPose to SMPL-24), :mod:`.transformers_backends` (ViTPose, SAM),
:mod:`.hmr2` (HMR2 adapter), :mod:`.appearance` (appearance from pixels).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from multithumbs.errors import InputError
from multithumbs.types import PersonTracks, Shots

SOURCES = ("blazepose", "phalp", "hmr2", "oracle")
DEFAULT_SPEC = "blazepose"
"""The perception ``run`` uses when none is given: it needs nothing beyond ``scripts/setup.sh``."""
REFINERS = ("vitpose", "sam")
HMR2_INSTALL_HINT = ("install 4DHumans' hmr2 package from its repository with its SMPL model and checkpoint, or "
                     "import 4DHumans results with phalp:RESULTS.pkl")
DEFAULT_MODELS = {"vitpose": "usyd-community/vitpose-base-simple", "sam": "facebook/sam-vit-base"}


@dataclass(frozen=True)
class SpecTerm:
    """One term of a perception spec.

    Attributes:
        backend: backend name (one of ``SOURCES`` or ``REFINERS``).
        argument: what follows the first ``:`` ("" when nothing does).
    """

    backend: str
    argument: str = ""

    def options(self) -> dict[str, str]:
        """``key=value`` pairs of the argument, separated by commas."""
        out = {}
        for part in filter(None, self.argument.split(",")):
            key, sep, value = part.partition("=")
            if not sep or not key:
                raise InputError(f"perception spec term {self.backend}:{self.argument}: expected key=value options, "
                                 f"got {part!r}")
            out[key.strip()] = value.strip()
        return out


def parse_spec(spec: str) -> list[SpecTerm]:
    """The terms of a perception spec (module docstring: the grammar), checked.

    Raises:
        InputError: empty spec, unknown backend (the message lists the known ones), no track source first,
            a second source, a missing path.
    """
    if not spec or not spec.strip():
        raise InputError("perception spec: empty; known backends: " + ", ".join(SOURCES + REFINERS))
    terms = []
    for raw in spec.split("+"):
        name, _, argument = raw.strip().partition(":")
        name = name.strip().lower()
        if name not in SOURCES + REFINERS:
            raise InputError(f"perception spec {spec!r}: unknown backend {name!r}; known backends: "
                             f"{', '.join(SOURCES + REFINERS)}")
        terms.append(SpecTerm(name, argument.strip()))
    if terms[0].backend not in SOURCES:
        raise InputError(f"perception spec {spec!r}: {terms[0].backend} refines existing tracks; start with a track "
                         f"source ({' or '.join(s + ':...' if s == 'phalp' else s for s in SOURCES)}), e.g. "
                         f"phalp:RESULTS.pkl+{spec}")
    if any(t.backend in SOURCES for t in terms[1:]):
        raise InputError(f"perception spec {spec!r}: only one track source ({', '.join(SOURCES)}) is allowed")
    if terms[0].backend in ("phalp", "oracle") and not terms[0].argument:
        raise InputError(f"perception spec {spec!r}: {terms[0].backend} needs a file, {terms[0].backend}:PATH")
    return terms


def check_backends(terms: list[SpecTerm]) -> None:
    """Refuse, before any work starts, a spec whose backends are not installed or whose files are missing
    (what :func:`load_perception` would find only after shot detection). Imports nothing heavy.

    Raises:
        InputError: hmr2 or detectron2 not installed, a missing ``detector``/``checkpoint`` file, a refiner
            without ``transformers``.
    """
    from multithumbs.extras import is_installed

    for term in terms:
        if term.backend == "blazepose":
            if term.argument:
                raise InputError(f"perception spec term blazepose:{term.argument}: blazepose takes no options")
            from multithumbs.perception.blazepose_models import check_models
            from multithumbs.perception.nanodet import check_models as check_person_detector

            check_models()
            check_person_detector()
        elif term.backend == "hmr2":
            options = term.options()
            unknown = set(options) - {"checkpoint", "detector"}
            if unknown:
                raise InputError(f"perception spec term hmr2: unknown option {sorted(unknown)[0]!r}; known: "
                                 f"checkpoint, detector")
            if not is_installed("hmr2"):
                raise InputError(f"perception backend 'hmr2': the hmr2 package is not installed; "
                                 f"{HMR2_INSTALL_HINT}")
            if not is_installed("detectron2"):
                raise InputError("perception backend 'hmr2': detectron2 is not installed (4DHumans detects people "
                                 "with its ViTDet model); install it, or import 4DHumans results with "
                                 "phalp:RESULTS.pkl")
            detector = options.get("detector")
            if detector is None or not Path(detector).is_file():
                raise InputError(f"perception backend 'hmr2': detector weights {detector!r} not found; pass the "
                                 f"local ViTDet checkpoint as hmr2:detector=PATH")
            if "checkpoint" in options and not Path(options["checkpoint"]).is_file():
                raise InputError(f"perception backend 'hmr2': checkpoint {options['checkpoint']} not found; "
                                 f"{HMR2_INSTALL_HINT}")
        elif term.backend == "oracle" and not Path(term.argument).is_file():
            raise InputError(f"perception spec term oracle: {term.argument}: no such ground-truth file")
        elif term.backend in REFINERS and not is_installed("transformers"):
            raise InputError(f"perception refiner {term.backend}: the transformers package is not installed "
                             f"(pip install 'multithumbs[learned]')")


def load_perception(spec: str, video_path: str | Path, shots: Shots, trust: bool = False, device: str = "auto",
                    appearance: bool = True, first_frame_number: int = 1, progress=None,
                    intrinsics: np.ndarray | None = None, model_keypoints: str = "reproject",
                    body=None) -> list[PersonTracks]:
    """Per-shot :class:`PersonTracks` of a video from the perception ``spec`` (module docstring).

    Args:
        spec: e.g. ``phalp:RESULTS.pkl``, ``hmr2``, ``phalp:RESULTS.pkl+vitpose+sam``.
        video_path: the video the results belong to (frames are read for refiners and appearance).
        shots: the video's shots; tracks are split at its cuts.
        trust: allow loading a pickle (``phalp:``), which runs code stored in the file.
        device: torch device of learned backends; ``"auto"``: CUDA when present
            (:func:`multithumbs.perception.hmr2.select_device`).
        appearance: describe appearance from pixels (off: appearance stays empty and invalid).
        first_frame_number: the number in the name of the video's first frame, for PHALP frames without
            ``time`` (PHALP's extractor counts from 1).
        progress: optional ``callable(stage: str, done: int, total: int)``.
        intrinsics: ``(3, 3)`` the camera the method will use (default: the 60° guess the method uses,
            :func:`multithumbs.scene.two_view.default_intrinsics`); ``blazepose`` fits its bodies in it. The keypoints of ``phalp`` and ``hmr2``
            are HMR2's mesh joints projected through its own camera, and are reprojected through this one
            (:func:`.model_keypoints.reproject_model_keypoints`) before any refiner replaces them.
        model_keypoints: what those keypoints become: ``"reproject"`` (default), ``"as_is"`` (HMR2's
            projections at confidence 1) or ``"none"`` (no 2D evidence); :data:`.model_keypoints.KEYPOINT_MODES`.
        body: the body model for the reprojection (default: :func:`multithumbs.body.model.load_body_model`).
    Raises:
        InputError: a one-line message naming the spec term, file, field or frame that is wrong.
    """
    from multithumbs.video import probe_video

    terms = parse_spec(spec)
    info = probe_video(video_path)
    if info.num_frames != shots.num_frames:
        raise InputError(f"{video_path}: {info.num_frames} frames but the shots cover {shots.num_frames}")
    step = (lambda stage: (lambda done, total: progress(stage, done, total))) if progress else (lambda stage: None)
    source = terms[0]
    uv = uv_valid = None
    if source.backend == "hmr2" or len(terms) > 1:
        from multithumbs.perception.hmr2 import select_device

        device = select_device(device)
    if source.backend == "phalp":
        from multithumbs.perception.phalp import load_phalp

        imported = load_phalp(source.argument, shots, info.image_size, trust=trust,
                              first_frame_number=first_frame_number, video_name=Path(video_path).stem)
        tracks, boxes = list(imported.tracks), list(imported.boxes)
        uv, uv_valid = imported.uv_appearance, imported.uv_valid
    elif source.backend == "blazepose":
        from multithumbs.perception.blazepose_backend import run_blazepose

        if intrinsics is None:
            from multithumbs.scene.two_view import default_intrinsics

            intrinsics = default_intrinsics(info.width, info.height)
        tracks = run_blazepose(video_path, shots, intrinsics, body,
                               progress=(lambda shot, done, total: progress(f"blazepose shot {shot + 1}/"
                                                                            f"{shots.num_shots}", done, total))
                               if progress else None)
        # The refiners prompt with boxes; only they need them, and they cost a pass over every mask.
        boxes = [people_boxes(tr) for tr in tracks] if len(terms) > 1 else []
    elif source.backend == "oracle":
        from multithumbs.body.model import load_body_model
        from multithumbs.io import load_ground_truth
        from multithumbs.perception.oracle import oracle_tracks

        truth, extras = load_ground_truth(source.argument)
        if truth.world.num_frames != shots.num_frames or not np.array_equal(truth.world.cut_frames, shots.cut_frames):
            raise InputError(f"perception spec term oracle: {source.argument} has {truth.world.num_frames} frames and "
                             f"cuts {truth.world.cut_frames.tolist()}; the video has {shots.num_frames} frames and "
                             f"cuts {shots.cut_frames.tolist()}")
        tracks = oracle_tracks(truth, load_body_model(), extras.get("instance"))
        boxes = [truth.bboxes[tr.track_ids, a:b] for tr, (a, b) in zip(tracks, shots.ranges)]
    else:
        from multithumbs.perception.hmr2 import run_hmr2

        options = source.options()
        unknown = set(options) - {"checkpoint", "detector"}
        if unknown:
            raise InputError(f"perception spec term hmr2: unknown option {sorted(unknown)[0]!r}; known: checkpoint, "
                             f"detector")
        tracks, boxes = run_hmr2(video_path, shots, options.get("checkpoint"), options.get("detector"), device,
                                 progress=step("hmr2"))
    if source.backend in ("phalp", "hmr2"):
        from multithumbs.perception.model_keypoints import reproject_model_keypoints

        if body is None and model_keypoints == "reproject":
            from multithumbs.body.model import load_body_model

            body = load_body_model()
        if intrinsics is None:
            from multithumbs.scene.two_view import default_intrinsics

            intrinsics = default_intrinsics(info.width, info.height)
        tracks = reproject_model_keypoints(tracks, intrinsics, body, model_keypoints)
    for term in terms[1:]:
        from multithumbs.perception.transformers_backends import load_sam, load_vitpose, refine_tracks

        model = term.argument or DEFAULT_MODELS[term.backend]
        if term.backend == "vitpose":
            tracks = refine_tracks(tracks, boxes, video_path, keypoints=load_vitpose(model, device),
                                   progress=step("vitpose"))
        else:
            tracks = refine_tracks(tracks, boxes, video_path, segmenter=load_sam(model, device),
                                   progress=step("sam"))
    if appearance:
        from multithumbs.perception.appearance import fill_appearance

        tracks = fill_appearance(tracks, video_path, uv, uv_valid, progress=step("appearance"))
    return tracks


def people_boxes(tracks: PersonTracks) -> np.ndarray:
    """``(P, T, 4)`` x0, y0, x1, y1 of each person's mask where valid (zeros elsewhere or where empty): the
    boxes refiners prompt with."""
    out = np.zeros((*tracks.valid.shape, 4))
    # One mask unpacked at a time: all of a long shot's at once is P x T x H x W bytes.
    for person, frame in zip(*np.nonzero(tracks.valid)):
        mask = tracks.mask(int(person), int(frame))
        r, c = np.flatnonzero(mask.any(1)), np.flatnonzero(mask.any(0))
        if r.size and c.size:
            out[person, frame] = (c[0], r[0], c[-1], r[-1])
    return out


__all__ = ["load_perception", "people_boxes", "DEFAULT_SPEC", "parse_spec", "check_backends", "SpecTerm", "SOURCES", "REFINERS", "DEFAULT_MODELS"]
