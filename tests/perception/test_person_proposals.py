"""HOG proposals for the people the face-anchored detector misses: boxes on a rendered frame, the square a
box gives with and without the detector's second look, crops at the frame's edge, a missing detector, and
the tracker following a person only a proposal shows."""

from pathlib import Path

import cv2
import numpy as np
import pytest

from multithumbs.errors import InputError
from multithumbs.perception import blazepose as bp
from multithumbs.perception import person_proposals
from multithumbs.perception.person_proposals import hog_boxes, proposal_roi, square_crop

FIXTURE = Path(__file__).parent / "fixtures" / "s09_frame63.png"


@pytest.fixture(scope="module")
def frame():
    return cv2.cvtColor(cv2.imread(str(FIXTURE)), cv2.COLOR_BGR2RGB)


def test_hog_finds_the_rendered_person_and_its_order_is_fixed(frame):
    boxes = hog_boxes(frame)
    assert boxes.ndim == 2 and boxes.shape[1] == 5 and len(boxes) >= 1
    assert (np.diff(boxes[:, 4]) <= 0).all() and (boxes[:, 4] >= 0.5).all()
    # The fixture's two walkers (orange at x 175-280, red at 305-430; y 45-315) each in a box of their size.
    for centre in ([228, 180], [368, 175]):
        inside = (boxes[:, 0] < centre[0]) & (centre[0] < boxes[:, 2]) & (boxes[:, 1] < centre[1]) & (centre[1] < boxes[:, 3])
        assert inside.any() and (boxes[inside, 3] - boxes[inside, 1] > 200).all()
    np.testing.assert_array_equal(hog_boxes(frame), boxes)
    assert len(hog_boxes(frame, min_weight=99.0)) == 0
    assert len(hog_boxes(np.full_like(frame, 90))) == 0   # nothing on a plain wall
    for size in ((120, 200), (100, 60), (10, 10)):   # smaller than HOG's window at some or all scales
        assert hog_boxes(np.full(size + (3,), 90, np.uint8)).shape == (0, 5)


def test_square_crop_is_black_beyond_the_frame():
    image = np.arange(20 * 30 * 3, dtype=np.uint8).reshape(20, 30, 3)
    crop, corner = square_crop(image, np.array([2.0, 3.0]), 8)
    np.testing.assert_array_equal(corner, [-2, -1])
    np.testing.assert_array_equal(crop[1:, 2:], image[:7, :6])
    assert not crop[0].any() and not crop[:, :2].any()


class OneDetection:
    """``detect`` gives one detection whose mid-hip is at ``hip`` in the image it is shown (or none)."""

    def __init__(self, hip):
        self.hip, self.calls = hip, 0

    def detect(self, image, min_score=0.5):
        self.calls += 1
        if self.hip is None:
            return []
        hip = np.asarray(self.hip, float)
        return [bp.Detection(0.9, np.r_[hip - 5, hip + 5], np.stack([hip, hip - [0, 40], hip, hip]))]


def test_the_detectors_second_look_gives_the_square_when_its_person_is_in_the_box(frame):
    box = np.array([100.0, 50.0, 150.0, 150.0, 1.0])            # 100 px tall, centre (125, 100)
    near = OneDetection(hip=(60.0, 50.0))                       # crop of 110 px from (70, 45): hip at (130, 95)
    roi, calls = proposal_roi(frame, box, near)
    assert calls == 1 and near.calls == 1
    np.testing.assert_allclose(roi.centre, [130, 95])
    assert roi.size == pytest.approx(2 * 40 * bp.ROI_SCALE) and roi.rotation == pytest.approx(0.0)
    far = OneDetection(hip=(1.0, 1.0))                          # someone else, 54 px off in x and y
    for model in (far, OneDetection(hip=None)):
        roi, calls = proposal_roi(frame, box, model, side=1.2)
        np.testing.assert_allclose(roi.centre, [125, 100])
        assert calls == 1 and roi.size == pytest.approx(120.0) and roi.rotation == 0.0
    unasked = OneDetection(hip=(60.0, 50.0))
    assert proposal_roi(frame, box, unasked, zoom=0)[1] == 0 and unasked.calls == 0


def test_a_missing_hog_detector_is_one_clear_error(monkeypatch, frame):
    person_proposals._people_detector.cache_clear()
    monkeypatch.delattr(cv2, "HOGDescriptor")
    with pytest.raises(InputError, match="HOG people detector"):
        hog_boxes(frame)
    monkeypatch.undo()
    person_proposals._people_detector.cache_clear()


def test_a_person_the_detector_never_gives_is_followed_from_a_proposal(monkeypatch):
    from multithumbs.perception import pose_tracking
    from multithumbs.perception.pose_tracking import TrackerConfig, track_shot
    from tests.perception.test_pose_tracking import COLOURS, ColourModel, identity_of, render

    class FaceBlind(ColourModel):
        palette = COLOURS   # reads every colour's landmarks, but its detector does not give green
        def detect(self, image, min_score=0.5):
            grey = image.copy()
            grey[np.all(image == COLOURS[1], axis=-1)] = 90
            return super().detect(grey, min_score)

    frames = render({0: [(100 + 5 * t, 120) for t in range(10)], 1: [(300, 120)] * 10}, 10)
    green_box = np.array([[280.0, 60.0, 320.0, 180.0, 1.0]])
    monkeypatch.setattr(pose_tracking, "hog_boxes", lambda frame, scales, min_weight: green_box)
    poses = track_shot(frames, FaceBlind())
    assert identity_of(poses, frames, 1, 0) is not None and len(poses.track_ids) == 2
    assert len({identity_of(poses, frames, 1, t) for t in range(10)}) == 1
    blind = track_shot(frames, FaceBlind(), TrackerConfig(proposals=False))
    assert len(blind.track_ids) == 1 and identity_of(blind, frames, 1, 0) is None


def test_a_person_detectors_boxes_replace_hogs_when_given(monkeypatch):
    from multithumbs.perception import pose_tracking
    from multithumbs.perception.pose_tracking import track_shot
    from tests.perception.test_pose_tracking import COLOURS, ColourModel, identity_of, render

    class FaceBlind(ColourModel):
        palette = COLOURS
        def detect(self, image, min_score=0.5):
            grey = image.copy()
            grey[np.all(image == COLOURS[1], axis=-1)] = 90
            return super().detect(grey, min_score)

    def no_hog(*args):
        raise AssertionError("HOG ran although a person detector was given")

    frames = render({0: [(100 + 5 * t, 120) for t in range(10)], 1: [(300, 120)] * 10}, 10)
    monkeypatch.setattr(pose_tracking, "hog_boxes", no_hog)
    seen = []
    poses = track_shot(frames, FaceBlind(), people=lambda f: seen.append(f) or np.array([[280.0, 60, 320, 180, 0.9]]))
    assert seen and identity_of(poses, frames, 1, 0) is not None and len(poses.track_ids) == 2
    nobody = track_shot(frames, FaceBlind(), people=lambda f: np.zeros((0, 5)))
    assert identity_of(nobody, frames, 1, 0) is None


def test_the_person_detector_is_chosen_by_the_config():
    import dataclasses

    from multithumbs.perception.blazepose_backend import BlazePoseConfig, person_proposals as chosen

    class Fake:
        def people(self, frame, min_score):
            return np.array([[0.0, 0, 1, 1, min_score]])

    config = BlazePoseConfig()
    assert config.person_detector == "nanodet"
    assert chosen(config, Fake())(None)[0, 4] == config.person_min_score
    assert chosen(dataclasses.replace(config, person_detector="hog")) is None
    off = dataclasses.replace(config, tracker=dataclasses.replace(config.tracker, proposals=False))
    assert chosen(off) is None
    with pytest.raises(InputError, match="'yolo': unknown"):
        chosen(dataclasses.replace(config, person_detector="yolo"))


def test_someone_partly_behind_a_followed_person_is_read_with_them_greyed_out():
    from multithumbs.perception.pose_tracking import TrackerConfig, track_shot
    from tests.perception.test_pose_tracking import COLOURS, ColourModel, identity_of, render

    class FaceBlind(ColourModel):
        palette = COLOURS   # its detector never gives green
        def detect(self, image, min_score=0.5):
            grey = image.copy()
            grey[np.all(image == COLOURS[1], axis=-1)] = 90
            return super().detect(grey, min_score)

    # Green stands behind red, 12 px of them showing at red's right; the proposal's centre is in red's box
    # and on the real frame the landmark pass reads red, the nearer colour.
    frames = render({0: [(200, 120)] * 8, 1: [(212, 120)] * 8}, 8, order=[1, 0])
    behind = np.array([[200.0, 60, 236, 180, 0.9]])
    poses = track_shot(frames, FaceBlind(), people=lambda f: behind)
    assert identity_of(poses, frames, 0, 0) is not None and identity_of(poses, frames, 1, 0) is not None
    assert len(poses.track_ids) == 2
    skipped = track_shot(frames, FaceBlind(), TrackerConfig(proposal_behind=False), people=lambda f: behind)
    assert len(skipped.track_ids) == 1 and identity_of(skipped, frames, 1, 0) is None
    # A proposal that is the followed person's own box (IoU >= proposal_same_iou) is never read again.
    same = track_shot(frames, FaceBlind(), people=lambda f: np.array([[182.0, 60, 220, 180, 0.9]]))
    assert len(same.track_ids) == 1


def test_the_person_detector_looks_every_proposal_every_frames():
    from multithumbs.perception.pose_tracking import TrackerConfig, track_shot
    from tests.perception.test_pose_tracking import ColourModel, render

    frames = render({0: [(100 + 5 * t, 120) for t in range(10)]}, 10)
    for every, expected in ((1, list(range(10))), (3, [0, 3, 6, 9])):
        looked = []
        track_shot(frames, ColourModel(), TrackerConfig(proposal_every=every),
                   people=lambda f: looked.append(next(t for t, g in enumerate(frames) if g is f)) or np.zeros((0, 5)))
        assert looked == expected, (every, looked)
