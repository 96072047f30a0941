"""Following a track back from where it was found, and splitting a track that moved onto someone else:
the tracker on coloured-box people (``test_pose_tracking``'s stand-in for BlazePose), with a detector
that, like BlazePose's face-anchored one, cannot see a person whose head shows only hair."""

import dataclasses

import numpy as np

from multithumbs.perception import blazepose as bp
from multithumbs.perception.backfill import backward_roi
from multithumbs.perception.pose_tracking import TrackerConfig, _Track, track_shot

from tests.perception.test_pose_tracking import ColourModel, H, W

PALETTE = np.array([[220, 40, 40], [40, 200, 40], [40, 40, 220], [220, 120, 40]], np.uint8)
"""Red, green, blue and an orange a reading of red's track finds 0.5 unlike red (between the tracker's
``split_dissimilarity`` and ``drift_dissimilarity``)."""
HAIR = np.array([10, 10, 10], np.uint8)


class FaceAnchoredModel(ColourModel):
    """:class:`ColourModel` on :data:`PALETTE`, whose detector skips people with hair over the top of their
    box (seen from behind); the landmark model reads them all the same."""

    palette = PALETTE

    def detect(self, image, min_score=0.5):
        seen = []
        for detection in super().detect(image, min_score):
            x, top = int(detection.face_box[0] + 5), int(detection.face_box[1])
            if not np.array_equal(image[max(top - 3, 0), x], HAIR):
                seen.append(detection)
        return seen


def render(people: dict[int, list], num_frames: int, order=None) -> list[np.ndarray]:
    """Person ``k`` a 40x120 box of ``PALETTE[k]`` at ``people[k][t]`` = ``(x, y, from_behind)`` or None;
    from behind, the box's top 12 rows are hair. Later people in ``order`` are in front."""
    frames = []
    for t in range(num_frames):
        image = np.full((H, W, 3), 90, np.uint8)
        for k in order or sorted(people):
            if people[k][t] is None:
                continue
            x, y, behind = people[k][t]
            image[y - 60:y + 60, x - 20:x + 20] = PALETTE[k]
            if behind:
                image[y - 60:y - 48, x - 20:x + 20] = HAIR
        frames.append(image)
    return frames


def identity(poses, frames, person: int, t: int) -> int | None:
    """The track id whose mask covers most of person ``person`` in frame ``t``."""
    mask = np.all(frames[t] == PALETTE[person], axis=-1)
    for i, track_id in enumerate(poses.track_ids):
        own = np.unpackbits(poses.masks[i, t], axis=-1)[:, :W].astype(bool)
        if poses.valid[i, t] and (own & mask).sum() > 0.5 * mask.sum():
            return int(track_id)
    return None


def test_a_person_walking_in_with_their_back_turned_is_followed_back_to_the_first_frame():
    n = 30
    turned = 12  # turns to face the camera in frame 12: the detector finds them then
    walker = [(60 + 5 * t, 120, t < turned) for t in range(n)]
    standing = [(330, 120, False)] * n
    frames = render({0: walker, 1: standing}, n)
    forward_only = track_shot(frames, FaceAnchoredModel(), TrackerConfig(backfill=0))
    assert identity(forward_only, frames, 0, turned - 1) is None
    poses = track_shot(frames, FaceAnchoredModel(), TrackerConfig(backfill=120))
    ids = [identity(poses, frames, 0, t) for t in range(n)]
    assert None not in ids and len(set(ids)) == 1
    assert identity(poses, frames, 1, 0) not in ids  # the fill did not take the other person
    assert poses.landmark_calls > forward_only.landmark_calls
    limited = track_shot(frames, FaceAnchoredModel(), TrackerConfig(backfill=5))
    assert [identity(limited, frames, 0, t) is not None for t in (turned - 6, turned - 5)] == [False, True]


def test_the_fill_stops_at_a_person_already_followed():
    n = 20
    # person 1 (found from frame 0) stands where person 0's fill would go; person 0 is hidden behind them
    # until frame 10, then steps out facing the camera
    hidden = [(200, 120, True) if t < 10 else (200 + 8 * (t - 9), 120, False) for t in range(n)]
    front = [(200, 120, False)] * n
    frames = render({0: hidden, 1: front}, n, order=[0, 1])
    # appearance off: its model would stop the fill too (red is not green); this is the geometric stop
    poses = track_shot(frames, FaceAnchoredModel(), TrackerConfig(backfill=120, appearance=False))
    own = identity(poses, frames, 1, 5)
    assert own is not None and all(identity(poses, frames, 1, t) == own for t in range(n))
    # person 0's track, found when they step out, was not followed back onto person 1
    stepped_out = identity(poses, frames, 0, 15)
    assert stepped_out is not None and stepped_out != own
    assert not poses.valid[list(poses.track_ids).index(stepped_out), :10].any()


def test_backward_roi_moves_on_by_the_motion_after_it():
    frames = render({0: [(100 + 6 * t, 120, False) for t in range(3)]}, 3)
    model = FaceAnchoredModel()
    track = _Track(0)
    for t in (1, 2):
        track.frames[t] = model.landmarks(frames[t], bp.Roi(np.array([100.0 + 6 * t, 126.0]), 200.0, 0.0))
    plain = backward_roi(dataclasses.replace(track, frames={1: track.frames[1]}), 0)
    moved = backward_roi(track, 0)
    assert np.allclose(moved.centre - plain.centre, [-3.0, 0.0])  # half the 6 px step, backwards


def test_a_track_that_moved_onto_an_unfollowed_person_is_split_there():
    n = 45
    # red (found at once) walks behind orange, whom the detector cannot see, waits there hidden for ten
    # frames, and walks out the other side
    red = [(80 + 6 * min(t, 20) + 6 * max(t - 30, 0), 120, False) for t in range(n)]
    orange = [(200, 120, True)] * n
    frames = render({0: red, 3: orange}, n, order=[0, 3])
    before, after = 5, n - 1
    split = track_shot(frames, FaceAnchoredModel(), TrackerConfig(backfill=120))
    assert identity(split, frames, 0, before) == identity(split, frames, 0, after)
    assert identity(split, frames, 0, before) not in {identity(split, frames, 3, t) for t in range(n)}
    assert identity(split, frames, 3, 0) is not None  # the split-off track, followed back to the start
    kept = track_shot(frames, FaceAnchoredModel(), TrackerConfig(backfill=120, split_frames=n))
    # without the split red's track carries on as orange, and red coming out is someone new
    assert identity(kept, frames, 0, before) != identity(kept, frames, 0, after)
    assert identity(kept, frames, 0, before) in {identity(kept, frames, 3, t) for t in range(n)}


class SmearingModel(FaceAnchoredModel):
    """:class:`FaceAnchoredModel` whose reading of red takes in the orange person beside them when there
    is one (as BlazePose's landmarks and segmentation spread over two people in one square)."""

    def landmarks(self, image, roi):
        found = super().landmarks(image, roi)
        red, orange = (np.all(image == PALETTE[k], axis=-1) for k in (0, 3))
        if not (found.presence and (found.segmentation.astype(bool) & red).any() and orange.any()):
            return found
        both = red | orange
        rows, cols = np.nonzero(both)
        points = found.image.copy()
        points[:33, 0] = np.linspace(cols.min(), cols.max(), 33)
        points[:33, 1] = np.linspace(rows.min(), rows.max(), 33)
        return dataclasses.replace(found, image=points, segmentation=both.astype(np.float32))


def test_a_split_of_a_person_read_poorly_for_a_while_is_merged_back():
    n = 40
    # orange, whom the detector cannot see, stands beside red for ten frames: red's readings take them in
    red = [(200, 120, False)] * n
    orange = [(240, 120, True) if 10 <= t < 20 else None for t in range(n)]
    frames = render({0: red, 3: orange}, n, order=[3, 0])
    # in this toy world the smeared readings are 0.28 unlike red's model, the clean ones 0.0
    config = TrackerConfig(backfill=120, split_dissimilarity=0.25)
    poses = track_shot(frames, SmearingModel(), config)
    ids = [identity(poses, frames, 0, t) for t in range(n)]
    assert None not in ids and len(set(ids)) == 1
    # the smeared readings did split the track: without the merge, red ends under three ids (the split
    # track's model learnt the smeared red, so the clean red splits it again), and the readings of each
    # split's streak, taken for a square in transit (track_split.drop_transit), are dropped
    apart = track_shot(frames, SmearingModel(), dataclasses.replace(config, merge_splits=False))
    ids = [identity(apart, frames, 0, t) for t in range(n)]
    assert len(set(ids) - {None}) == 3
    assert [t for t in range(n) if ids[t] is None] == [10, 11, 12, 20, 21, 22]


class SloppyDetector(ColourModel):
    """:class:`ColourModel` whose detections sit ``offset`` px right of the person (a detector's loose box)
    and whose readings keep, in their world landmarks, the centre of the square they were read in."""

    offset = 15.0

    def detect(self, image, min_score=0.5):
        return [dataclasses.replace(d, keypoints=d.keypoints + [self.offset, 0.0], face_box=d.face_box + self.offset)
                for d in super().detect(image, min_score)]

    def landmarks(self, image, roi):
        found = super().landmarks(image, roi)
        return dataclasses.replace(found, world=np.tile([*roi.centre, roi.size], (33, 1)))


def test_a_runs_first_frames_are_read_again_in_the_squares_of_the_frames_after_them():
    from tests.perception.test_pose_tracking import render as render_boxes

    n, speed = 12, 4.0
    frames = render_boxes({0: [(100 + speed * t, 120) for t in range(n)]}, n)
    centre = [np.array([100 + speed * t, 60 + 0.55 * 120]) for t in range(n)]   # where the reading centres
    plain = track_shot(frames, SloppyDetector(), TrackerConfig(reread=0, backfill=0))
    again = track_shot(frames, SloppyDetector(), TrackerConfig(reread=3, backfill=0))
    assert plain.track_ids.size == again.track_ids.size == 1

    def square_error(poses, t):
        return float(np.hypot(*(poses.world[0, t, 0, :2] - centre[t])))

    assert square_error(plain, 0) > 10                     # read in the detection's loose square
    assert all(square_error(again, t) < 6 for t in range(3))
    np.testing.assert_array_equal(plain.world[0, 3:], again.world[0, 3:])   # later frames as read forwards
    assert again.landmark_calls == plain.landmark_calls + 3
    np.testing.assert_array_equal(plain.masks, again.masks)                 # masks stay as settled
