"""A followed person's square read again with the others greyed out (multithumbs/perception/behind.py), on
the coloured-box frames of test_pose_tracking, seen by a stand-in that, like BlazePose, reads the most
prominent person in its square."""

import numpy as np

from multithumbs.perception import blazepose as bp
from multithumbs.perception.behind import pixels, read_behind
from multithumbs.perception.pose_tracking import TrackerConfig, _Track, landmark_box, track_shot
from tests.perception.test_pose_tracking import ColourModel, identity_of, render


class ProminentModel(ColourModel):
    """``landmarks``: the colour with the most pixels in the square (greyed-out pixels are no colour), read
    as :class:`ColourModel` reads it; nobody when no colour has more than 150 pixels there."""

    def __init__(self):
        super().__init__()
        self.landmark_calls = 0

    def landmarks(self, image, roi):
        self.landmark_calls += 1
        inside = roi.mask(image.shape[:2])
        people = self._people(image)
        counts = {k: int((mask & inside).sum()) for k, (_, mask) in people.items()}
        shown = [k for k, c in counts.items() if c > 150]
        if not shown:
            return super().landmarks(np.full_like(image, 90), roi)
        box, mask = people[max(shown, key=counts.get)]
        alone = np.full_like(image, 90)
        alone[mask] = image[mask]
        hip = np.array([(box[0] + box[2]) / 2, box[1] + 0.55 * (box[3] - box[1])])
        return super().landmarks(alone, bp.Roi(hip, roi.size, roi.rotation))


def _other(found):
    """A reading as ``read_behind`` takes the frame's other people: its landmark box and its pixels."""
    return landmark_box(found), pixels(found, TrackerConfig().paint_probability)


def _walks_behind(n=30):
    """Red stands at x = 200; green walks in from the right and stops 32 px to red's right, behind red: 32
    of green's 40 px show, and red, whole, has more pixels in green's square than green."""
    red = [(200, 120)] * n
    green = [(360 - 8 * t, 120) if t < 17 else (232, 120) for t in range(n)]
    return render({0: red, 1: green}, n, order=[1, 0])


def test_someone_partly_behind_stays_followed():
    frames = _walks_behind()
    poses = track_shot(frames, ProminentModel())
    green = {identity_of(poses, frames, 1, t) for t in range(len(frames))}
    assert None not in green and len(green) == 1
    red = {identity_of(poses, frames, 0, t) for t in range(len(frames))}
    assert None not in red and len(red) == 1 and red != green


def test_without_it_the_square_reads_the_person_in_front_and_the_track_is_lost():
    frames = _walks_behind()
    poses = track_shot(frames, ProminentModel(), TrackerConfig(read_behind=False))
    lost = [t for t in range(len(frames)) if identity_of(poses, frames, 1, t) is None]
    assert lost and min(lost) < 17 < max(lost)


def test_no_one_else_in_the_square_means_no_second_reading():
    frames = render({0: [(100, 120)], 1: [(300, 120)]}, 1)
    model = ProminentModel()
    far = model.landmarks(frames[0], bp.Roi(np.array([300.0, 126]), 180.0, 0.0))
    calls = model.landmark_calls
    got, used = read_behind(frames[0], bp.Roi(np.array([100.0, 126]), 180.0, 0.0), _Track(0), [_other(far)], model,
                            TrackerConfig())
    assert got is None and used == 0 and model.landmark_calls == calls


def test_a_wholly_hidden_person_gives_nothing_and_a_half_seen_one_their_own_box():
    # Green wholly hidden: with red greyed out the square holds no one, and nothing is taken.
    frames = render({0: [(200, 120)], 1: [(200, 120)]}, 1, order=[1, 0])
    model = ProminentModel()
    square = bp.Roi(np.array([205.0, 126]), 180.0, 0.0)
    red = model.landmarks(frames[0], square)
    got, used = read_behind(frames[0], square, _Track(1), [_other(red)], model, TrackerConfig())
    assert got is None and used == 1
    # Green half in view beside red: taken, and it is green's box.
    frames = render({0: [(200, 120)], 1: [(220, 120)]}, 1, order=[1, 0])
    red = model.landmarks(frames[0], square)
    got, _ = read_behind(frames[0], square, _Track(1), [_other(red)], model, TrackerConfig())
    assert got is not None and got[0].image[:33, 0].min() >= 220


def test_someone_who_walks_out_from_behind_is_followed_back_behind():
    # Time reversed: green starts behind red and walks out to the right. The forward pass cannot find
    # them while their square reads red; the backward fill follows them back behind red (backfill.py).
    frames = _walks_behind()[::-1]
    poses = track_shot(frames, ProminentModel())
    assert {identity_of(poses, frames, 1, t) for t in range(len(frames))} == {identity_of(poses, frames, 1, 29)}
    for config in (TrackerConfig(read_behind=False), TrackerConfig(backfill=0)):
        poses = track_shot(frames, ProminentModel(), config)
        assert identity_of(poses, frames, 1, 0) is None and identity_of(poses, frames, 1, 29) is not None


def test_a_reading_behind_someone_that_lies_down_is_not_taken():
    frames = render({0: [(200, 120)], 1: [(220, 120)]}, 1, order=[1, 0])
    square = bp.Roi(np.array([205.0, 126]), 180.0, 0.0)
    model = ProminentModel()
    red = model.landmarks(frames[0], square)

    class Lying(ProminentModel):
        def __init__(self, degrees):
            super().__init__()
            self.turn = np.radians(degrees)

        def landmarks(self, image, roi):
            found = super().landmarks(image, roi)
            hip, top = found.image[33, :2], found.image[34, :2]
            d = top - hip  # turn the body axis about the hip
            c, s = np.cos(self.turn), np.sin(self.turn)
            points = found.image.copy()
            points[34, :2] = hip + [c * d[0] - s * d[1], s * d[0] + c * d[1]]
            return bp.Landmarks(found.presence, points, found.world, found.segmentation, found.roi)

    for degrees, taken in ((30, True), (60, False), (-80, False)):
        got, _ = read_behind(frames[0], square, _Track(1), [_other(red)], Lying(degrees), TrackerConfig())
        assert (got is not None) == taken, degrees
    got, _ = read_behind(frames[0], square, _Track(1), [_other(red)], Lying(60),
                         TrackerConfig(behind_max_roll=np.radians(90)))
    assert got is not None


def test_a_second_reading_that_is_still_the_person_in_front_is_not_taken():
    # A stand-in that reads red whatever was greyed out: its reading is red's box and pixels, so it is
    # someone else's, and it is refused.
    frames = render({0: [(200, 120)], 1: [(220, 120)]}, 1, order=[1, 0])
    square = bp.Roi(np.array([205.0, 126]), 180.0, 0.0)
    red = ProminentModel().landmarks(frames[0], square)

    class SeesRed(ProminentModel):
        def landmarks(self, image, roi):
            self.landmark_calls += 1
            return red

    got, used = read_behind(frames[0], square, _Track(1), [_other(red)], SeesRed(), TrackerConfig())
    assert got is None and used == 1
