"""Where else to look for people: boxes of a whole-body person detector, for those the face-anchored one misses.

The boxes come from NanoDet (:mod:`.nanodet`, the default: ``BlazePoseConfig.person_detector``) or from
OpenCV's HOG pedestrian detector (:func:`hog_boxes`, below); :func:`proposal_roi` turns either into the
landmark model's square.

BlazePose's detector finds a person from their face. People seen from behind, side-on, or without a
readable face (the suite's mannequins: a person wholly seen in s07 scores nothing above 0.1 at any scale) are
never given, and recall stops at 0.86 (``docs/RESULTS.md``). The HOG people detector (Dalal and Triggs,
OpenCV's default linear SVM on 64x128 windows) looks at the silhouette instead. Its boxes are proposals:

- :func:`hog_boxes` runs it on the frame and on the frame at half size (people over 256 px tall are
  found more surely there, and it costs a quarter), best first;
- :func:`proposal_roi` turns a box into the landmark model's square. The face-anchored detector is first
  asked again on a square crop around the box, where the person fills its view; when it finds someone whose
  mid-hip lies within half the box's height of its centre, the square comes from its alignment points (the path every detection takes).
  Otherwise the square is the box's own: centred on it, upright, ``side`` times its height. A track seeded
  from a bare box read a person's first frames badly and kept reading them badly (s01), which the second
  look avoids.

The tracker (:mod:`.pose_tracking`) takes a proposal only after the landmark pass in that square confirms a
person with the checks every detection passes. OpenCV keeps the HOG detector in ``objdetect`` up to 4.x and
in the contrib modules from 5.0 on, hence ``opencv-contrib-python-headless``.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from multithumbs.errors import InputError
from multithumbs.perception import blazepose as bp


@lru_cache(maxsize=1)
def _people_detector():
    import cv2

    if not hasattr(cv2, "HOGDescriptor"):
        raise InputError(f"OpenCV {cv2.__version__}: no HOG people detector (cv2.HOGDescriptor); OpenCV 5 keeps it "
                         "in opencv-contrib-python-headless, which scripts/setup.sh installs")
    hog = cv2.HOGDescriptor()
    hog.setSVMDetector(cv2.HOGDescriptor_getDefaultPeopleDetector())
    return hog


def hog_boxes(frame: np.ndarray, scales: tuple[float, ...] = (1.0, 0.5), min_weight: float = 0.5) -> np.ndarray:
    """``(N, 5)`` x0, y0, x1, y1 (frame pixels) and SVM margin of the people HOG sees in an ``(H, W, 3)``
    frame looked at in each of ``scales``, margins at least ``min_weight``, best first (ties by position,
    so the order never depends on OpenCV's threads). Scales at which the frame is smaller than HOG's 64x128
    window are skipped."""
    import cv2

    hog = _people_detector()
    window_w, window_h = hog.winSize
    found = []
    for scale in scales:
        h, w = (int(round(n * scale)) for n in frame.shape[:2])
        if w < window_w or h < window_h:
            continue  # OpenCV's detectMultiScale crashes on an image smaller than its window
        image = frame if scale == 1 else cv2.resize(frame, (w, h), interpolation=cv2.INTER_AREA)
        rects, weights = hog.detectMultiScale(image, winStride=(8, 8), padding=(8, 8), scale=1.05)
        for (x, y, box_w, box_h), weight in zip(np.asarray(rects, np.float64).reshape(-1, 4), np.ravel(weights)):
            if weight >= min_weight:
                found.append([x / scale, y / scale, (x + box_w) / scale, (y + box_h) / scale, float(weight)])
    boxes = np.asarray(found, np.float64).reshape(-1, 5)
    return boxes[np.lexsort((boxes[:, 1], boxes[:, 0], -boxes[:, 4]))]


def square_crop(frame: np.ndarray, centre: np.ndarray, side: int) -> tuple[np.ndarray, np.ndarray]:
    """The ``(side, side, 3)`` square of ``frame`` centred on ``centre`` (black beyond its edges) and the
    ``(2,)`` frame position of the crop's top-left pixel."""
    h, w = frame.shape[:2]
    corner = np.floor(np.asarray(centre, np.float64) - side / 2).astype(int)
    crop = np.zeros((side, side, 3), np.uint8)
    x0, y0 = max(corner[0], 0), max(corner[1], 0)
    x1, y1 = min(corner[0] + side, w), min(corner[1] + side, h)
    if x1 > x0 and y1 > y0:
        crop[y0 - corner[1]:y1 - corner[1], x0 - corner[0]:x1 - corner[0]] = frame[y0:y1, x0:x1]
    return crop, corner


def proposal_roi(frame: np.ndarray, box: np.ndarray, model, side: float = 1.2, zoom: float = 1.1,
                 min_score: float = bp.MIN_DETECTION_SCORE) -> tuple[bp.Roi, int]:
    """The landmark model's square for a HOG box ``(4+,)`` (module docstring) and the detector calls made.

    Args:
        model: anything with BlazePose's ``detect(image, min_score)``.
        side: the bare box's square side, as a multiple of its height.
        zoom: the crop the detector looks at again, as a multiple of the box's height (0: not asked).
    """
    box = np.asarray(box, np.float64)
    centre, height = 0.5 * (box[:2] + box[2:4]), float(box[3] - box[1])
    if zoom <= 0:
        return bp.Roi(centre, side * height, 0.0), 0
    crop, corner = square_crop(frame, centre, max(int(round(zoom * height)), 1))
    found = model.detect(crop, min_score=min_score)
    if found:  # the best detection only
        hip, size_point = found[0].keypoints[0] + corner, found[0].keypoints[1] + corner
        if np.all(np.abs(hip - centre) <= height / 2):
            return bp.roi_from_points(hip, size_point), 1
    return bp.Roi(centre, side * height, 0.0), 1


__all__ = ["hog_boxes", "square_crop", "proposal_roi"]
