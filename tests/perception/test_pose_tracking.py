"""Following several people through a shot: the tracker's logic on frames whose 'people' are coloured
boxes, seen by a stand-in for BlazePose that reads the colours (so greying out, crossings, occlusions,
entries and exits are real image events, and the models' accuracy is not what is tested here)."""

import numpy as np
import pytest

from multithumbs.perception import blazepose as bp
from multithumbs.perception.pose_tracking import ShotPoses, TrackerConfig, box_iou, track_shot

H, W = 240, 400
COLOURS = np.array([[220, 40, 40], [40, 200, 40], [40, 40, 220], [200, 200, 40]], np.uint8)


class ColourModel:
    """``detect``: one detection per person colour visible in the image (greyed-out pixels are not a
    colour), the largest first. ``landmarks``: the colour nearest the square's centre, its box as landmarks."""

    palette = COLOURS

    def __init__(self):
        self.detector_calls = 0

    @classmethod
    def _people(cls, image):
        out = {}
        for k, colour in enumerate(cls.palette):
            mask = np.all(image == colour, axis=-1)
            if mask.sum() > 150:
                rows, cols = np.nonzero(mask)
                out[k] = (np.array([cols.min(), rows.min(), cols.max(), rows.max()], float), mask)
        return out

    def detect(self, image, min_score=0.5):
        self.detector_calls += 1
        people = sorted(self._people(image).items(), key=lambda kv: -kv[1][1].sum())
        out = []
        for _, (box, _) in people:
            hip = np.array([(box[0] + box[2]) / 2, box[1] + 0.55 * (box[3] - box[1])])
            top = hip - [0, 0.6 * (box[3] - box[1])]
            out.append(bp.Detection(0.9, np.array([hip[0] - 5, box[1], hip[0] + 5, box[1] + 10]), np.stack(
                [hip, top, hip - [0, 10], top])))
        return out

    def landmarks(self, image, roi):
        people = self._people(image)
        best, distance = None, np.inf
        for k, (box, mask) in people.items():
            centre = np.array([(box[0] + box[2]) / 2, box[1] + 0.55 * (box[3] - box[1])])
            d = np.hypot(*(centre - roi.centre))
            if d < distance and d < roi.size / 2:
                best, distance = k, d
        points = np.zeros((39, 5))
        segmentation = np.zeros((H, W), np.float32)
        presence = 0.0
        if best is not None:
            box, mask = people[best]
            presence = 1.0
            u = np.linspace(box[0], box[2], 33)
            v = np.linspace(box[1], box[3], 33)
            points[:33] = np.column_stack([u, v, np.zeros(33), np.ones(33), np.ones(33)])
            hip = np.array([(box[0] + box[2]) / 2, box[1] + 0.55 * (box[3] - box[1])])
            points[33, :2], points[34, :2] = hip, hip - [0, 0.6 * (box[3] - box[1])]
            segmentation = mask.astype(np.float32)
        return bp.Landmarks(presence, points, np.zeros((33, 3)), segmentation, roi)


def render(positions: dict[int, list[tuple[float, float] | None]], num_frames: int, order=None) -> list[np.ndarray]:
    """Frames with person ``k`` a 40x120 box of ``COLOURS[k]`` centred at ``positions[k][t]`` (None: absent);
    later people in ``order`` are drawn in front."""
    frames = []
    for t in range(num_frames):
        image = np.full((H, W, 3), 90, np.uint8)
        for k in order or sorted(positions):
            where = positions[k][t]
            if where is None:
                continue
            x, y = (int(round(c)) for c in where)
            image[max(y - 60, 0):y + 60, max(x - 20, 0):x + 20] = COLOURS[k]
        frames.append(image)
    return frames


def identity_of(poses: ShotPoses, frames, person: int, t: int) -> int | None:
    """The track id covering the person of colour ``person`` in frame ``t``, from the tracks' masks."""
    mask = np.all(frames[t] == COLOURS[person], axis=-1)
    for i, track_id in enumerate(poses.track_ids):
        if poses.valid[i, t]:
            own = np.unpackbits(poses.masks[i, t], axis=-1)[:, :W].astype(bool)
            if (own & mask).sum() > 0.5 * mask.sum():
                return int(track_id)
    return None


def test_two_people_cross_and_keep_their_ids():
    n = 30
    a = [(60 + 9 * t, 120) for t in range(n)]
    b = [(340 - 9 * t, 125) for t in range(n)]
    frames = render({0: a, 1: b}, n)
    poses = track_shot(frames, ColourModel())
    assert poses.image.shape == (len(poses.track_ids), n, 33, 5)
    ids_a = {identity_of(poses, frames, 0, t) for t in range(n)} - {None}
    ids_b = {identity_of(poses, frames, 1, t) for t in range(n)} - {None}
    assert len(ids_a) == 1 and len(ids_b) == 1 and ids_a != ids_b
    assert poses.valid.sum() >= 2 * n - 4  # at most a couple of frames lost while they overlap


def test_greying_out_finds_everyone_in_the_first_frame():
    frames = render({k: [(60 + 90 * k, 120)] * 8 for k in range(4)}, 8)
    poses = track_shot(frames, ColourModel())
    assert len(poses.track_ids) == 4
    assert poses.valid[:, 0].all()


def test_a_person_hidden_for_a_few_frames_comes_back_with_the_same_id():
    n = 24
    a = [(200, 120)] * n
    b = [(120, 120) if not 8 <= t < 12 else (200, 120) for t in range(n)]  # walks behind a for 4 frames
    frames = render({0: a, 1: b}, n, order=[1, 0])
    poses = track_shot(frames, ColourModel(), TrackerConfig(max_missed=6))
    before = identity_of(poses, frames, 1, 5)
    after = identity_of(poses, frames, 1, 15)
    assert before is not None and before == after


def test_people_entering_and_leaving_get_new_ids_and_nothing_is_reused():
    n = 30
    a = [(100, 120) if t < 12 else None for t in range(n)]
    b = [None if t < 18 else (300, 120) for t in range(n)]
    frames = render({0: a, 1: b}, n)
    poses = track_shot(frames, ColourModel(), TrackerConfig(max_missed=3))
    assert len(set(poses.track_ids.tolist())) == len(poses.track_ids) == 2
    assert identity_of(poses, frames, 0, 5) != identity_of(poses, frames, 1, 25)
    assert not poses.valid[:, 12:18].any()


def test_empty_shot_and_no_people():
    empty = track_shot([], ColourModel())
    assert empty.valid.shape == (0, 0)
    nobody = track_shot(render({}, 4), ColourModel())
    assert nobody.track_ids.size == 0 and nobody.valid.shape == (0, 4)


def test_redetection_interval_bounds_detector_calls():
    frames = render({0: [(200, 120)] * 20}, 20)
    model = ColourModel()
    poses = track_shot(frames, model, TrackerConfig(redetect_every=5))
    assert poses.valid.all()
    # frame 0: the round that finds the person, then one that finds nobody (whole frame and tiles); then
    # every 5th frame only the round that finds nobody (the one person is greyed out)
    assert model.detector_calls == 1 + 4 * (1 + TrackerConfig().tiles)


def test_box_iou():
    assert box_iou(np.array([0, 0, 2, 2.0]), np.array([1, 1, 3, 3.0])) == pytest.approx(1 / 7)
    assert box_iou(np.array([0, 0, 1, 1.0]), np.array([2, 2, 3, 3.0])) == 0.0


def test_a_figure_smaller_than_min_height_starts_no_track():
    # a 14 x 12 px "person" (a figure in a poster) beside a real one: its landmarks span 11 px, 0.046 of
    # the frame's height
    frames = render({0: [(100, 120)] * 10}, 10)
    for frame in frames:
        frame[40:52, 300:314] = COLOURS[1]
    poses = track_shot(frames, ColourModel())
    assert len(poses.track_ids) == 1
    assert len(track_shot(frames, ColourModel(), TrackerConfig(min_height=0.03)).track_ids) == 2
