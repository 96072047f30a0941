import joblib
import numpy as np
import pytest

from multithumbs.errors import InputError
from multithumbs.geometry import reexpress_for_intrinsics
from multithumbs.perception.joints import OPENPOSE25_TO_SMPL24
from multithumbs.perception.model_keypoints import reproject_model_keypoints
from multithumbs.perception.phalp import frame_index, import_phalp, load_phalp, read_phalp_results
from multithumbs.perception.phalp_export import confirmed_runs, export_phalp

MAPPED = sorted(OPENPOSE25_TO_SMPL24.values())


def _check_same(original, imported, body):
    """Imported tracks are the originals: ids + 1 (PHALP counts from 1), SMPL, camera, masks; keypoints are
    HMR2's projections of the same joints, so reprojected through the original camera they are the joints
    the original mesh projects to."""
    assert len(original) == len(imported)
    for a, b in zip(original, imported):
        order = np.argsort(a.track_ids)

        def pick(x, order=order):
            return x[order]

        np.testing.assert_array_equal(pick(a.track_ids) + 1, b.track_ids)
        np.testing.assert_array_equal(pick(a.valid), b.valid)
        v = b.valid
        for name in ("global_orient", "body_pose"):
            np.testing.assert_allclose(pick(getattr(a, name))[v], getattr(b, name)[v], atol=1e-6, err_msg=name)
        # PHALP's camera is for HMR2's focal length: converted back, the translation is the original.
        rest = body.rest_pelvis(b.betas)[:, None]
        np.testing.assert_allclose(pick(a.transl)[v], (reexpress_for_intrinsics(b.transl + rest, b.K, a.K) - rest)[v],
                                   atol=1e-4)
        np.testing.assert_allclose(pick(a.betas), b.betas, atol=1e-6)
        np.testing.assert_array_equal(pick(a.masks), b.masks)
        # The file's 2d_joints are HMR2-camera projections: the importer's keypoints are exactly its own
        # mesh through its own camera ...
        own = reproject_model_keypoints([b], b.K, body)[0].keypoints2d
        inside = b.keypoints2d[..., 2] > 0
        np.testing.assert_allclose(own[..., :2][inside], b.keypoints2d[..., :2][inside], atol=2e-2)
        # ... and through the original camera they are where the original mesh projects.
        back = reproject_model_keypoints([b], a.K, body)[0].keypoints2d
        mesh = reproject_model_keypoints([a], a.K, body)[0].keypoints2d
        both = (back[..., 2] > 0) & (pick(mesh)[..., 2] > 0)
        assert both[v].any()
        np.testing.assert_allclose(back[..., :2][both], pick(mesh)[..., :2][both], atol=2e-2)
        assert np.all(np.delete(b.keypoints2d, MAPPED, axis=2)[..., 2] == 0)
        assert b.start_frame == a.start_frame and b.image_size == a.image_size


def test_round_trip_perfect_perception(perfect_tracks, scene, body, tmp_path):
    video, shots = scene
    uv = [np.random.default_rng(k).normal(size=(*tr.valid.shape, 16)) for k, tr in enumerate(perfect_tracks)]
    path = export_phalp(tmp_path / "r.pkl", perfect_tracks, shots, body, uv_appearance=uv, detect_shots=True,
                        n_init=1)
    imported = load_phalp(path, shots, video.truth.world.image_size, trust=True)
    _check_same(perfect_tracks, imported.tracks, body)
    np.testing.assert_array_equal(imported.phalp_cut_frames, shots.cut_frames)
    for k, tr in enumerate(imported.tracks):
        np.testing.assert_allclose(imported.uv_appearance[k][tr.valid], uv[k][tr.valid], atol=1e-6)
        np.testing.assert_array_equal(imported.uv_valid[k], tr.valid)
        assert imported.boxes[k].shape == (*tr.valid.shape, 4)
        assert not tr.appearance_valid.any()


def test_round_trip_noisy_perception(noisy_tracks, scene, body, results_file):
    # Shuffled ids, missed frames (written as ghosts) and eroded masks survive the trip.
    video, shots = scene
    imported = load_phalp(results_file, shots, video.truth.world.image_size, trust=True)
    _check_same(noisy_tracks, imported.tracks, body)
    assert imported.uv_appearance is None


def test_pickle_structure_is_phalps(results_file, scene):
    results = joblib.load(results_file)
    _, shots = scene
    assert len(results) == shots.num_frames
    keys = sorted(results)
    assert keys[0].endswith("_DEMO/video/img/000001.jpg") and keys[-1].endswith(f"{shots.num_frames:06d}.jpg")
    assert [results[k]["time"] for k in keys] == list(range(shots.num_frames))
    assert not any(f["shot"] for f in results.values())  # PHALP's detect_shots is off by default
    frame = next(f for f in results.values() if f["tid"])
    assert frame["smpl"][0]["global_orient"].shape == (1, 3, 3)
    assert frame["smpl"][0]["body_pose"].shape == (23, 3, 3)
    assert frame["smpl"][0]["betas"].shape == (10,)
    assert frame["camera"][0].shape == (3,) and frame["2d_joints"][0].shape == (90,)
    assert frame["3d_joints"][0].shape == (45, 3) and frame["camera_bbox"][0].shape == (3,)
    w, h = frame["scale"][0]
    assert w / h == pytest.approx(192 / 256) and w >= frame["bbox"][0][2] - 1e-4 and h >= frame["bbox"][0][3] - 1e-4
    assert set(frame["mask"][0][0]) == {"size", "counts"} and isinstance(frame["mask"][0][0]["counts"], str)
    assert len(frame["bbox"][0]) == 4 and min(min(f["tid"], default=1) for f in results.values()) >= 1


def test_lost_tracks_are_listed_as_ghosts(results_file, noisy_tracks, scene):
    # The noisy perception misses frames; PHALP keeps listing a lost track with stale values.
    results = joblib.load(results_file)
    ghosts = [(f, k) for f in results.values() for k, t in enumerate(f["tracked_time"]) if t > 0]
    assert ghosts
    for frame, k in ghosts:
        assert frame["tid"][k] not in frame["tracked_ids"]
    # ... and the importer does not take them for detections (the round trip checks valid exactly).
    assert sum(len(f["tid"]) for f in results.values()) > sum(int(tr.valid.sum()) for tr in noisy_tracks)


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
    assert frame_index("outputs//_DEMO/v/img/000123.jpg") == 122  # PHALP numbers frames from 1
    assert frame_index("frame_7.png", first=0) == 7
    with pytest.raises(InputError, match="stream timestamp"):
        frame_index(("video.mp4", 5))
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
    beyond = dict(results, **{"outputs//_DEMO/video/img/000017.jpg": dict(first, time=16)})
    with pytest.raises(InputError, match=r"000017.jpg' \(index 16\) is beyond the end of the video \(16 frames\)") as e:
        import_phalp(beyond, shots, video.truth.world.image_size)
    _one_line(e)
    unnamed = {k: v for k, v in results.items()}
    unnamed["outputs//_DEMO/video/img/cover.jpg"] = {k: v for k, v in first.items() if k != "time"}
    with pytest.raises(InputError, match="cover.jpg': the name has no frame number"):
        import_phalp(unnamed, shots, video.truth.world.image_size)
    twice = dict(results, **{"outputs//_DEMO/video/img/1.jpg": first})
    with pytest.raises(InputError, match="both name frame 0"):
        import_phalp(twice, shots, video.truth.world.image_size)


def test_export_refuses_to_overwrite(results_file, noisy_tracks, scene, body, tmp_path):
    before = results_file.read_bytes()
    with pytest.raises(InputError, match="already exists"):
        export_phalp(results_file, noisy_tracks, scene[1], body)
    assert results_file.read_bytes() == before
    copy = tmp_path / "copy.pkl"
    copy.write_bytes(before)
    export_phalp(copy, noisy_tracks, scene[1], body, overwrite=True, n_init=1)


def test_export_checks_shots(noisy_tracks, scene, body, tmp_path):
    with pytest.raises(InputError, match="2 track sets for 1 shots"):
        from multithumbs.types import Shots

        export_phalp(tmp_path / "x.pkl", noisy_tracks, Shots(np.zeros(0, int), 30.0, 16, np.zeros(16)), body)
    assert not list(tmp_path.iterdir())


def test_a_track_is_confirmed_after_five_consecutive_hits():
    # DeepSORT (PHALP.py:232-244): a tentative track that misses a frame is deleted; at the 5th
    # consecutive hit the track is confirmed and its first frames back-filled.
    assert confirmed_runs([0, 1, 2, 3, 4, 6, 9]) == [0, 1, 2, 3, 4, 6, 9]
    assert confirmed_runs([0, 1, 3, 4, 5, 6, 7, 8]) == [3, 4, 5, 6, 7, 8]
    assert confirmed_runs([0, 1, 2, 3]) == []
    assert confirmed_runs([2, 5], n_init=1) == [2, 5]


def test_truncated_file_loads_aligned_by_time(results_file, noisy_tracks, scene):
    # PHALP stops below video.end_frame (1300 by default): the frames it has stay where their time says.
    video, shots = scene
    results = {k: v for k, v in joblib.load(results_file).items() if v["time"] < 12}
    imported = import_phalp(results, shots, video.truth.world.image_size)
    for a, b in zip(noisy_tracks, imported.tracks):
        frames = a.start_frame + np.arange(a.num_frames)
        order = np.argsort(a.track_ids)
        kept = b.track_ids - 1
        rows = [list(a.track_ids[order]).index(t) for t in kept]
        np.testing.assert_array_equal(a.valid[order][rows] & (frames < 12), b.valid)
        np.testing.assert_allclose(a.body_pose[order][rows][b.valid], b.body_pose[b.valid], atol=1e-6)


def test_name_and_time_that_disagree_are_refused(results_file, scene):
    video, shots = scene
    results = joblib.load(results_file)
    key = sorted(results)[3]
    results[key] = dict(results[key], time=2)  # a run with another start_frame: names and time disagree
    with pytest.raises(InputError, match=r"000004.jpg'.*video frame 3 .*'time' is 2") as e:
        import_phalp(results, shots, video.truth.world.image_size, source="r.pkl")
    assert _one_line(e).startswith("r.pkl: ")


def test_tuple_keys_are_placed_by_time(results_file, noisy_tracks, scene, body):
    # extract_video=False: keys (video_path, pts), pts a stream timestamp (phalp/utils/io.py:81).
    video, shots = scene
    results = joblib.load(results_file)
    by_pts = {("/data/video.mp4", 512 * f["time"] + 1000): f for f in results.values()}
    imported = import_phalp(by_pts, shots, video.truth.world.image_size, video_name="video")
    plain = import_phalp(results, shots, video.truth.world.image_size)
    for a, b in zip(plain.tracks, imported.tracks):
        np.testing.assert_array_equal(a.valid, b.valid)
        np.testing.assert_array_equal(a.transl, b.transl)
    untimed = {k: {n: v for n, v in f.items() if n != "time"} for k, f in by_pts.items()}
    with pytest.raises(InputError, match="stream timestamp") as e:
        import_phalp(untimed, shots, video.truth.world.image_size)
    _one_line(e)


def test_results_of_another_video_are_refused(results_file, scene):
    video, shots = scene
    with pytest.raises(InputError, match="results are of video 'video'.*not of 'clip'") as e:
        import_phalp(joblib.load(results_file), shots, video.truth.world.image_size, video_name="clip")
    _one_line(e)
