"""Shot detection with PySceneDetect (DESIGN §1 stage 1) and the choice of clean boundary frames.

:func:`detect_shots` runs one of scenedetect's detectors (adaptive by default, content or histogram as
options) over a video file or an array of frames and returns :class:`~multithumbs.types.Shots` with
the cut frames (first frame of each new shot) and a per-frame change score for diagnostics: the
detector's frame-to-frame content score (``content_val``: mean HSV difference to the previous frame,
0..255) for the adaptive and content detectors, one minus the luma-histogram correlation for the
histogram detector. Frame 0 has score 0.

With ``reject_flash_frames`` (the default) a one-frame outlier, a glitched or flashed frame unlike both
neighbours (:mod:`multithumbs.scene.glitches`), is replaced by a neighbour before the detector sees
it, so it makes no cut and does not move a true cut next to it; the scores are those of the frames
the detector saw, and ``Shots.outlier_frames`` names the replaced frames.

:func:`boundary_frames` picks the two frames a shared space is built from at a cut. The conventions'
pair is ``(t_b - 1, t_b)``; when the scores around the cut say the transition is not a clean hard cut
(a fade or dissolve spreads the change over several frames, or the detector placed the cut one frame
off), it steps away from the cut until each frame is steady, so no mixed frame enters the shared space,
and it steps past outlier frames, so no corrupted frame does either.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from multithumbs.errors import InputError
from multithumbs.scene.glitches import without_outliers
from multithumbs.types import Shots

DETECTORS = ("adaptive", "content", "histogram")


@dataclass(frozen=True)
class ShotConfig:
    """Shot detection settings (scenedetect's defaults unless said otherwise).

    Attributes:
        detector: ``"adaptive"`` (default), ``"content"`` or ``"histogram"``.
        adaptive_threshold: adaptive detector: ratio of a frame's score to its neighbours' mean that
            makes a cut.
        adaptive_window: adaptive detector: frames on each side averaged for that ratio.
        min_content_val: adaptive detector: smallest content score a cut may have.
        content_threshold: content detector: content score (0..255) that makes a cut.
        histogram_threshold: histogram detector: a cut when one minus the luma-histogram correlation of
            two consecutive frames reaches this. Default 0.02, not scenedetect's 0.2: shots of one room
            share their luma histogram (standard suite: cuts 0.03-0.15, within shots at most 0.01).
        histogram_bins: histogram detector: number of luma bins (scenedetect's default).
        min_shot_length: fewest frames of a shot; a cut closer than this to the previous one is
            ignored (scenedetect's ``min_scene_len``). Default 8 frames (0.27 s at 30 fps): scenedetect's
            15 would merge the short shots of fast edits.
        downscale_width: frames are shrunk to about this width before detection (scenedetect's own
            speed-up, which its SceneManager applies by default); 0 keeps the full size.
        reject_flash_frames: find one-frame outliers (a glitch or flash) and show the detector a
            neighbour instead, so they make no cut and move none
            (:func:`~multithumbs.scene.glitches.without_outliers`). A genuine one-frame shot is dropped
            with them. False runs the detector on the frames as they are.
        flash_min_spike: smallest spike score of an outlier (mean excess of the frame over both
            neighbours where they agree, 0..255). Default 1: on clean footage the only frame isolated as
            below is a synthetic hard cut's first frame, at 0.5 (OpenCV's sample videos: none); a white
            block on a sixteenth of the frame scores 3 next to a cut and 6 in mid-shot, a full-frame
            flash 45 and more. On OpenCV's ``Megamind_bugy.avi`` (23 frames of 5-120 corrupted, some by
            a small bar) it finds 18 of them and no other frame.
        flash_isolation: how many times an outlier's spike score exceeds its neighbours'. Default 2: fast
            motion raises the score of several frames in a row (clean footage: at most 1.4 times its
            neighbours, with scores up to 3.0 on the shaky ``tree.avi``), a glitch of one frame only.
    """

    detector: str = "adaptive"
    adaptive_threshold: float = 3.0
    adaptive_window: int = 2
    min_content_val: float = 15.0
    content_threshold: float = 27.0
    histogram_threshold: float = 0.02
    histogram_bins: int = 128
    min_shot_length: int = 8
    downscale_width: int = 256
    reject_flash_frames: bool = True
    flash_min_spike: float = 1.0
    flash_isolation: float = 2.0

    def __post_init__(self) -> None:
        if self.detector not in DETECTORS:
            raise InputError(f"detector {self.detector!r}: choose from {', '.join(DETECTORS)}")
        if self.min_shot_length < 1:
            raise InputError(f"min_shot_length: at least 1 frame, got {self.min_shot_length}")
        if self.adaptive_window < 1:
            raise InputError(f"adaptive_window: at least 1 frame, got {self.adaptive_window}")
        if not self.flash_min_spike > 0:
            raise InputError(f"flash_min_spike: must be positive, got {self.flash_min_spike}")
        if not self.flash_isolation >= 1:
            raise InputError(f"flash_isolation: at least 1, got {self.flash_isolation}")


def _make_detector(config: ShotConfig):
    from scenedetect import AdaptiveDetector, ContentDetector, HistogramDetector

    if config.detector == "adaptive":
        return AdaptiveDetector(adaptive_threshold=config.adaptive_threshold, window_width=config.adaptive_window,
                                min_content_val=config.min_content_val, min_scene_len=config.min_shot_length)
    if config.detector == "content":
        return ContentDetector(threshold=config.content_threshold, min_scene_len=config.min_shot_length)
    return HistogramDetector(threshold=config.histogram_threshold, bins=config.histogram_bins,
                             min_scene_len=config.min_shot_length)


def _frames_of(source) -> tuple[Iterable[np.ndarray], float, str]:
    """Frames (RGB uint8), fps and a name for messages, from a path or an array ``(T, H, W, 3)``."""
    if isinstance(source, (str, Path)):
        from multithumbs.video import iter_frames, probe_video

        info = probe_video(source)
        return iter_frames(source), info.fps, str(source)
    frames = np.asarray(source)
    if frames.ndim != 4 or frames.shape[-1] != 3 or frames.dtype != np.uint8:
        raise InputError(f"frames: expected (T, H, W, 3) uint8 RGB, got {frames.shape} {frames.dtype}")
    if len(frames) == 0:
        raise InputError("frames: the video has no frames")
    return iter(frames), 30.0, "frames"


def _downscaled(frames: Iterable[np.ndarray], width: int) -> Iterator[np.ndarray]:
    """RGB frames -> BGR frames shrunk to about ``width`` (0: full size), the detector's input."""
    size = None
    for rgb in frames:
        if size is None:
            h, w = rgb.shape[:2]
            scale = width / w if 0 < width < w else 1.0
            size = (max(1, round(w * scale)), max(1, round(h * scale))) if scale != 1.0 else ()
        bgr = cv2.cvtColor(np.ascontiguousarray(rgb), cv2.COLOR_RGB2BGR)
        yield cv2.resize(bgr, size, interpolation=cv2.INTER_AREA) if size else bgr


def detect_shots(source, config: ShotConfig = ShotConfig(), fps: float | None = None) -> Shots:
    """Cuts of a video by scenedetect.

    Args:
        source: a video file path, or frames ``(T, H, W, 3)`` uint8 RGB.
        config: detector settings.
        fps: frame rate of an array of frames (default 30); a file's own rate is read from it.
    Returns:
        :class:`Shots` with ``source="scenedetect:<detector>"``, per-frame change scores and the
        one-frame outliers the detector did not see (``outlier_frames``; empty without
        ``config.reject_flash_frames``).
    """
    from multithumbs.extras import require

    require("scenedetect", "shot detection")  # not a pip dependency of the project (multithumbs.extras)
    from scenedetect import FrameTimecode, StatsManager

    frames, file_fps, name = _frames_of(source)
    rate = float(fps) if fps is not None and not isinstance(source, (str, Path)) else file_fps
    if not rate > 0:
        raise InputError(f"fps: must be positive, got {rate}")
    detector = _make_detector(config)
    stats = StatsManager()
    detector.stats_manager = stats
    small = _downscaled(frames, config.downscale_width)
    seen = (without_outliers(small, config.flash_min_spike, config.flash_isolation) if config.reject_flash_frames
            else ((bgr, False) for bgr in small))
    cuts: list[int] = []
    outliers: list[int] = []
    count = 0
    last_code = None
    for index, (bgr, outlier) in enumerate(seen):
        last_code = FrameTimecode(index, rate)
        cuts += [c.frame_num for c in detector.process_frame(last_code, bgr)]
        if outlier:
            outliers.append(index)
        count = index + 1
    if count == 0:
        raise InputError(f"{name}: the video has no frames")
    cuts += [c.frame_num for c in detector.post_process(last_code)]
    key = "content_val" if config.detector != "histogram" else f"hist_diff [bins={config.histogram_bins}]"
    scores = np.zeros(count)
    for index in range(1, count):
        (value,) = stats.get_metrics(FrameTimecode(index, rate), [key])
        if value is not None:
            scores[index] = (1.0 - value) if config.detector == "histogram" else value
    cut_frames = np.array(sorted({c for c in cuts if 0 < c < count}), dtype=np.int64)
    return Shots(cut_frames=cut_frames, fps=rate, num_frames=count, scores=scores,
                 source=f"scenedetect:{config.detector}", outlier_frames=np.array(outliers, dtype=np.int64))


@dataclass(frozen=True)
class BoundaryPair:
    """The two frames a shared space is built from at one cut.

    Attributes:
        cut_frame: ``t_b``.
        before: frame of the earlier shot (``t_b - 1`` for a clean hard cut).
        after: frame of the later shot (``t_b`` for a clean hard cut).
    """

    cut_frame: int
    before: int
    after: int

    @property
    def shifted(self) -> bool:
        """True when the pair is not the conventions' ``(t_b - 1, t_b)``."""
        return (self.before, self.after) != (self.cut_frame - 1, self.cut_frame)


def boundary_frames(shots: Shots, cut_index: int, max_offset: int = 4, steady_factor: float = 3.0,
                    steady_floor: float = 2.0) -> BoundaryPair:
    """Clean boundary frames of cut ``cut_index``, stepping away from a transition that is not a hard cut.

    A frame ``f`` before the cut is clean when the change into it, ``scores[f]``, is steady; a frame
    after it is clean when the change out of it, ``scores[f + 1]``, is steady. Steady means at most
    ``max(steady_floor, steady_factor * median score)`` of the shot (the cut's own score excluded).
    A detector one frame late or early, or a fade, therefore moves the pair off the mixed frames. A frame
    in ``shots.outlier_frames`` (a glitch or flash) is never chosen: the pair steps on past it.

    Args:
        shots: detected shots with scores (all-zero scores, as for ground-truth shots, give ``(t_b-1, t_b)``).
        cut_index: which cut.
        max_offset: farthest step from the cut on each side; the pair stays inside both shots.
    """
    if not 0 <= cut_index < shots.cut_frames.size:
        raise InputError(f"cut_index: {cut_index} is not a cut of a video with {shots.cut_frames.size} cuts")
    cut = int(shots.cut_frames[cut_index])
    (a0, a1), (b0, b1) = shots.ranges[cut_index], shots.ranges[cut_index + 1]
    scores = shots.scores
    near = np.zeros(shots.num_frames, bool)
    near[max(cut - max_offset - 1, 0):cut + max_offset + 2] = True

    def steady_level(lo: int, hi: int) -> float:
        inside = scores[lo + 1:hi][~near[lo + 1:hi]]
        typical = float(np.median(inside)) if inside.size else 0.0
        return max(steady_floor, steady_factor * typical)

    level_a, level_b = steady_level(a0, a1), steady_level(b0, b1)
    before = cut - 1
    while before > max(a0, cut - 1 - max_offset) and scores[before] > level_a:
        before -= 1
    after = cut
    while after < min(b1 - 1, cut + max_offset) and after + 1 < shots.num_frames and scores[after + 1] > level_b:
        after += 1
    # An outlier's score is that of its stand-in, so it can look steady: step past it whatever the offset,
    # staying inside the shot (a shot made of outliers only keeps its last or first frame).
    odd = set(shots.outlier_frames.tolist())
    while before in odd and before > a0:
        before -= 1
    while after in odd and after < b1 - 1:
        after += 1
    return BoundaryPair(cut, before, after)
