import numpy as np
import pytest

from multithumbs.errors import InputError
from multithumbs.types import CameraTrajectory, PersonTracks, SharedSpace, Shots, pack_mask, unpack_mask


def _tracks(p=2, t=5, h=9, w=13, **over):
    fields = dict(
        shot_index=0, start_frame=0, track_ids=np.arange(p), global_orient=np.zeros((p, t, 3)),
        body_pose=np.zeros((p, t, 23, 3)), betas=np.zeros((p, 10)), transl=np.zeros((p, t, 3)),
        keypoints2d=np.zeros((p, t, 24, 3)), masks=np.zeros((p, t, h, (w + 7) // 8), np.uint8),
        image_size=(h, w), K=np.eye(3), appearance=np.zeros((p, t, 4)),
        appearance_valid=np.zeros((p, t), bool), valid=np.ones((p, t), bool))
    fields.update(over)
    return PersonTracks(**fields)


def test_person_tracks_accepts_consistent_shapes():
    tr = _tracks()
    assert tr.num_people == 2 and tr.num_frames == 5


@pytest.mark.parametrize("field,value,needle", [
    ("transl", np.zeros((2, 6, 3)), "T"),
    ("body_pose", np.zeros((2, 5, 24, 3)), "body_pose"),
    ("betas", np.zeros((3, 10)), "P"),
    ("masks", np.zeros((2, 5, 9, 1), np.uint8), "masks"),
    ("valid", np.ones((2, 5)), "dtype"),
    ("track_ids", np.array([4, 4]), "unique"),
])
def test_person_tracks_rejects_bad_shapes_with_named_field(field, value, needle):
    with pytest.raises(InputError, match=needle) as err:
        _tracks(**{field: value})
    assert "PersonTracks" in str(err.value) and "\n" not in str(err.value)


def test_shots_ranges_and_validation():
    shots = Shots(np.array([4, 9]), 30.0, 12, np.zeros(12))
    assert shots.ranges == [(0, 4), (4, 9), (9, 12)]
    np.testing.assert_array_equal(shots.shot_of_frame(), [0] * 4 + [1] * 5 + [2] * 3)
    with pytest.raises(InputError, match="cut_frames"):
        Shots(np.array([0, 5]), 30.0, 12, np.zeros(12))
    with pytest.raises(InputError, match="num_frames"):
        Shots(np.array([], int), 30.0, 0, np.zeros(0))


def test_mask_packing_round_trip():
    rng = np.random.default_rng(0)
    mask = rng.random((3, 7, 13)) > 0.5
    packed = pack_mask(mask)
    assert packed.shape == (3, 7, 2) and packed.dtype == np.uint8
    np.testing.assert_array_equal(unpack_mask(packed, 13), mask)


def test_camera_and_shared_space_contracts():
    CameraTrajectory(0, 0, np.eye(3), np.tile(np.eye(3), (4, 1, 1)), np.zeros((4, 3)))
    with pytest.raises(InputError, match="CameraTrajectory.t"):
        CameraTrajectory(0, 0, np.eye(3), np.tile(np.eye(3), (4, 1, 1)), np.zeros((5, 3)))
    SharedSpace(10, np.tile(np.eye(3), (2, 1, 1)), np.tile(np.eye(3), (2, 1, 1)), np.zeros((2, 3)),
                np.zeros((6, 3)), np.zeros((2, 6, 2)), np.ones((2, 6), bool), np.ones(6), (4, 4))
    with pytest.raises(InputError, match="N"):
        SharedSpace(10, np.tile(np.eye(3), (2, 1, 1)), np.tile(np.eye(3), (2, 1, 1)), np.zeros((2, 3)),
                    np.zeros((6, 3)), np.zeros((2, 5, 2)), np.ones((2, 6), bool), np.ones(6), (4, 4))


def test_people_mask_is_the_union_of_valid_masks():
    import numpy as np

    from multithumbs.types import PersonTracks, pack_mask

    h, w, T = 4, 10, 2
    masks = np.zeros((2, T, h, w), bool)
    masks[0, 0, 0, 0] = masks[1, 0, 3, 9] = masks[1, 1, 2, 2] = True
    valid = np.array([[True, True], [True, False]])
    tr = PersonTracks(0, 0, np.array([0, 1]), np.zeros((2, T, 3)), np.zeros((2, T, 23, 3)), np.zeros((2, 10)),
                      np.zeros((2, T, 3)), np.zeros((2, T, 24, 3)), pack_mask(masks), (h, w), np.eye(3),
                      np.zeros((2, T, 1)), np.zeros((2, T), bool), valid)
    union = tr.people_mask()
    assert union.shape == (T, h, w)
    assert union[0, 0, 0] and union[0, 3, 9] and not union[1].any()  # person 1 is not valid at frame 1


def test_people_mask_of_chosen_frames_matches_the_whole_shot():
    import numpy as np

    from multithumbs.types import PersonTracks, pack_mask

    rng = np.random.default_rng(0)
    masks = rng.random((3, 5, 6, 11)) > 0.7
    valid = rng.random((3, 5)) > 0.3
    tr = PersonTracks(0, 0, np.arange(3), np.zeros((3, 5, 3)), np.zeros((3, 5, 23, 3)), np.zeros((3, 10)),
                      np.zeros((3, 5, 3)), np.zeros((3, 5, 24, 3)), pack_mask(masks), (6, 11), np.eye(3),
                      np.zeros((3, 5, 1)), np.zeros((3, 5), bool), valid)
    np.testing.assert_array_equal(tr.people_mask([4, 1]), tr.people_mask()[[4, 1]])
    np.testing.assert_array_equal(tr.people_mask(), (masks & valid[:, :, None, None]).any(0))
