import joblib
import numpy as np
import pytest

from multithumbs.errors import InputError
from multithumbs.geometry import reexpress_for_intrinsics
from multithumbs.perception.joints import OPENPOSE25_TO_SMPL24
from multithumbs.perception.phalp import export_phalp, frame_index, import_phalp, load_phalp, read_phalp_results

MAPPED = sorted(OPENPOSE25_TO_SMPL24.values())


def _check_same(original, imported, keypoint_atol=1e-4):
    assert len(original) == len(imported)
    for a, b in zip(original, imported):
        order = np.argsort(a.track_ids)

        def pick(x, order=order):
            return x[order]

        np.testing.assert_array_equal(pick(a.track_ids), b.track_ids)
        np.testing.assert_array_equal(pick(a.valid), b.valid)
        v = b.valid
        for name in ("global_orient", "body_pose"):
            np.testing.assert_allclose(pick(getattr(a, name))[v], getattr(b, name)[v], atol=1e-6, err_msg=name)
        # PHALP's camera is for HMR2's focal length: converted back, the translation is the original.
        np.testing.assert_allclose(pick(a.transl)[v], reexpress_for_intrinsics(b.transl, b.K, a.K)[v], atol=1e-6)
        np.testing.assert_allclose(pick(a.betas), b.betas, atol=1e-6)
        np.testing.assert_array_equal(pick(a.masks), b.masks)
        kp_a, kp_b = pick(a.keypoints2d)[v][:, MAPPED], b.keypoints2d[v][:, MAPPED]
        inside = kp_b[..., 2] > 0
        np.testing.assert_allclose(kp_a[..., :2][inside], kp_b[..., :2][inside], atol=keypoint_atol)
        assert np.all(np.delete(b.keypoints2d, MAPPED, axis=2)[..., 2] == 0)
        assert b.start_frame == a.start_frame and b.image_size == a.image_size


def test_round_trip_perfect_perception(perfect_tracks, scene, tmp_path):
    video, shots = scene
    uv = [np.random.default_rng(k).normal(size=(*tr.valid.shape, 16)) for k, tr in enumerate(perfect_tracks)]
    path = export_phalp(tmp_path / "r.pkl", perfect_tracks, shots, uv_appearance=uv)
    imported = load_phalp(path, shots, video.truth.world.image_size, trust=True)
    _check_same(perfect_tracks, imported.tracks)
    np.testing.assert_array_equal(imported.phalp_cut_frames, shots.cut_frames)
    for k, tr in enumerate(imported.tracks):
        np.testing.assert_allclose(imported.uv_appearance[k][tr.valid], uv[k][tr.valid], atol=1e-6)
        np.testing.assert_array_equal(imported.uv_valid[k], tr.valid)
        assert imported.boxes[k].shape == (*tr.valid.shape, 4)
        assert not tr.appearance_valid.any()


def test_round_trip_noisy_perception(noisy_tracks, scene, results_file):
    # Shuffled ids, missed frames and eroded masks survive the trip.
    video, shots = scene
    imported = load_phalp(results_file, shots, video.truth.world.image_size, trust=True)
    _check_same(noisy_tracks, imported.tracks)
    assert imported.uv_appearance is None


def test_pickle_structure_is_phalps(results_file, scene):
    results = joblib.load(results_file)
    _, shots = scene
    assert len(results) == shots.num_frames
    key = sorted(results)[0]
    assert key.endswith("000000.jpg")
    frame = next(f for f in results.values() if f["tid"])
    assert frame["smpl"][0]["global_orient"].shape == (1, 3, 3)
    assert frame["smpl"][0]["body_pose"].shape == (23, 3, 3)
    assert frame["smpl"][0]["betas"].shape == (10,)
    assert frame["camera"][0].shape == (3,) and frame["2d_joints"][0].shape == (90,)
    assert set(frame["mask"][0][0]) == {"size", "counts"} and isinstance(frame["mask"][0][0]["counts"], str)
    assert len(frame["bbox"][0]) == 4


def test_predicted_entries_are_not_detections(results_file, scene):
    # PHALP lists lost tracks with their last state; only 'tracked_ids' are observations.
    video, shots = scene
    results = joblib.load(results_file)
    key = next(k for k, f in results.items() if f["tid"])
    tid = results[key]["tid"][0]
    results[key]["tracked_ids"] = [t for t in results[key]["tracked_ids"] if t != tid]
    imported = import_phalp(results, shots, video.truth.world.image_size)
    f = results[key]["time"]
    shot = int(shots.shot_of_frame()[f])
    tr = imported.tracks[shot]
    i = list(tr.track_ids).index(tid)
    assert not tr.valid[i, f - tr.start_frame]


def test_frame_index():
    assert frame_index("_DEMO/v/img/000123.jpg") == 123
    assert frame_index("frame_7.png", offset=1) == 6
    assert frame_index(("video.mp4", 5)) == 5
    with pytest.raises(InputError, match="no frame number"):
        frame_index("_DEMO/v/img/first.jpg")


def _one_line(excinfo):
    assert "\n" not in str(excinfo.value)
    return str(excinfo.value)


def test_trust_is_required(results_file, scene):
    with pytest.raises(InputError, match="trust") as e:
        load_phalp(results_file, scene[1], (96, 160))
    _one_line(e)


def test_missing_and_unreadable_files(tmp_path, scene):
    with pytest.raises(InputError, match="no such results file"):
        read_phalp_results(tmp_path / "none.pkl", trust=True)
    bad = tmp_path / "bad.pkl"
    bad.write_text("not a pickle")
    with pytest.raises(InputError, match="not a readable") as e:
        read_phalp_results(bad, trust=True)
    _one_line(e)


@pytest.mark.parametrize("content, match", [
    ([1, 2, 3], "top level is list"),
    ({}, "empty dict"),
    ({"frame_000.jpg": {"boxes": [], "scores": []}}, "different tool"),
])
def test_pickle_from_another_tool(tmp_path, scene, content, match):
    path = tmp_path / "other.pkl"
    joblib.dump(content, path)
    with pytest.raises(InputError, match=match) as e:
        load_phalp(path, scene[1], (96, 160), trust=True)
    _one_line(e)


def _edited(results_file, edit):
    results = joblib.load(results_file)
    key = next(k for k, f in results.items() if len(f["tid"]))
    edit(results, key)
    return results, key


@pytest.mark.parametrize("edit, match", [
    (lambda r, k: r[k].pop("smpl"), "missing field 'smpl'"),
    (lambda r, k: r[k].pop("camera"), "missing field 'camera'"),
    (lambda r, k: r[k]["smpl"][0].pop("betas"), "missing field 'smpl.betas'"),
    (lambda r, k: r[k]["smpl"][0].update(body_pose=np.zeros((21, 3, 3))), "smpl.body_pose"),
    (lambda r, k: r[k]["camera"].append(np.zeros(3)), "field 'camera' has"),
    (lambda r, k: r[k]["size"].__setitem__(0, [720, 1280]), "720x1280 does not match the video"),
    (lambda r, k: r[k]["camera"].__setitem__(0, np.array([0, np.nan, 1.0])), "non-finite"),
    (lambda r, k: r[k]["mask"][0][0].update(size=[10, 10]), "mask size"),
])
def test_bad_fields_name_frame_and_field(results_file, scene, edit, match):
    video, shots = scene
    results, key = _edited(results_file, edit)
    with pytest.raises(InputError, match=match) as e:
        import_phalp(results, shots, video.truth.world.image_size)
    assert key in _one_line(e)


def test_frames_beyond_the_video_and_unmatched_names(results_file, scene):
    video, shots = scene
    results = joblib.load(results_file)
    first = next(iter(results.values()))
    beyond = dict(results, **{"_DEMO/video/img/000016.jpg": first})
    with pytest.raises(InputError, match=r"000016.jpg' \(index 16\) is beyond the end of the video \(16 frames\)") as e:
        import_phalp(beyond, shots, video.truth.world.image_size)
    _one_line(e)
    unnamed = dict(results, **{"_DEMO/video/img/cover.jpg": first})
    with pytest.raises(InputError, match="cover.jpg': the name has no frame number"):
        import_phalp(unnamed, shots, video.truth.world.image_size)
    twice = dict(results, **{"_DEMO/video/img/0000.jpg": first})
    with pytest.raises(InputError, match="both name frame 0"):
        import_phalp(twice, shots, video.truth.world.image_size)


def test_export_refuses_to_overwrite(results_file, noisy_tracks, scene):
    before = results_file.read_bytes()
    with pytest.raises(InputError, match="already exists"):
        export_phalp(results_file, noisy_tracks, scene[1])
    assert results_file.read_bytes() == before
    export_phalp(results_file, noisy_tracks, scene[1], overwrite=True)


def test_export_checks_shots(noisy_tracks, scene, tmp_path):
    with pytest.raises(InputError, match="2 track sets for 1 shots"):
        from multithumbs.types import Shots

        export_phalp(tmp_path / "x.pkl", noisy_tracks, Shots(np.zeros(0, int), 30.0, 16, np.zeros(16)))
    assert not list(tmp_path.iterdir())
