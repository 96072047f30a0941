"""ViTPose and SAM adapters on tiny random models loaded the real way (local files only, HF_HUB_OFFLINE=1)."""

from pathlib import Path

import numpy as np
import pytest

from multithumbs.errors import InputError
from multithumbs.perception.blazepose_models import missing_models
from multithumbs.perception.joints import COCO17_TO_SMPL24
from multithumbs.perception.phalp import load_phalp
from multithumbs.perception.transformers_backends import load_sam, load_vitpose, refine_tracks

MAPPED = sorted(COCO17_TO_SMPL24.values())
UNMAPPED = [j for j in range(24) if j not in MAPPED]


@pytest.fixture(autouse=True)
def _offline(monkeypatch, one_torch_thread):
    monkeypatch.setenv("HF_HUB_OFFLINE", "1")


def test_vitpose_keypoints_in_smpl_layout(tiny_models):
    estimator = load_vitpose(tiny_models["vitpose"])
    frame = np.random.default_rng(0).integers(0, 255, (96, 160, 3), dtype=np.uint8)
    boxes = np.array([[10.0, 5.0, 50.0, 90.0], [80.0, 20.0, 120.0, 80.0]])
    kp = estimator(frame, boxes)
    assert kp.shape == (2, 24, 3)
    assert np.all(kp[:, UNMAPPED] == 0)
    assert np.all((kp[:, MAPPED, 2] >= 0) & (kp[:, MAPPED, 2] <= 1))
    # Heatmap peaks map back into each box (ViTPose pads boxes by 1.25).
    for box, person in zip(boxes, kp):
        centre, half = (box[:2] + box[2:]) / 2, (box[2:] - box[:2]) / 2 * 1.25 * np.array([1.0, 1.0])
        side = np.maximum(half, half[::-1] * np.array([48 / 64, 64 / 48]))
        assert np.all(np.abs(person[MAPPED, :2] - centre) <= 1.5 * side)
    assert estimator(frame, np.zeros((0, 4))).shape == (0, 24, 3)


def test_sam_masks_per_box(tiny_models):
    segmenter = load_sam(tiny_models["sam"])
    frame = np.random.default_rng(1).integers(0, 255, (96, 160, 3), dtype=np.uint8)
    masks = segmenter(frame, np.array([[10.0, 5.0, 50.0, 90.0], [80.0, 20.0, 120.0, 80.0]]))
    assert masks.shape == (2, 96, 160) and masks.dtype == bool
    assert segmenter(frame, np.zeros((0, 4))).shape == (0, 96, 160)


def test_models_load_only_from_local_files(tmp_path, tiny_models):
    with pytest.raises(InputError, match="not loadable from a local folder or the Hugging Face cache") as e:
        load_vitpose(tmp_path / "nothing")
    assert "\n" not in str(e.value)
    with pytest.raises(InputError, match="SAM model"):
        load_sam("facebook/not-in-the-cache-model")
    with pytest.raises(InputError, match="predicts 5 keypoints"):
        load_vitpose(tiny_models["vitpose5"])


def test_refine_tracks_end_to_end(tiny_models, scene, results_file, video_file):
    video, shots = scene
    imported = load_phalp(results_file, shots, video.truth.world.image_size, trust=True)
    first = imported.tracks[:1]  # one shot keeps the test short
    refined = refine_tracks(first, imported.boxes[:1], video_file, keypoints=load_vitpose(tiny_models["vitpose"]),
                            segmenter=load_sam(tiny_models["sam"]))
    for before, after in zip(first, refined):
        v = before.valid
        assert after.keypoints2d.shape == before.keypoints2d.shape
        assert np.all(after.keypoints2d[v][:, UNMAPPED, 2] == 0)
        assert not np.array_equal(after.keypoints2d[v], before.keypoints2d[v])      # replaced by ViTPose
        np.testing.assert_array_equal(after.keypoints2d[~v], before.keypoints2d[~v])  # untouched where not seen
        np.testing.assert_array_equal(after.masks[~v], before.masks[~v])
        np.testing.assert_array_equal(after.global_orient, before.global_orient)


def test_refine_tracks_needs_the_whole_video(tiny_models, scene, results_file):
    video, shots = scene
    imported = load_phalp(results_file, shots, video.truth.world.image_size, trust=True)
    with pytest.raises(InputError, match="ends at frame"):
        refine_tracks(imported.tracks, imported.boxes, video.frames[:10], keypoints=load_vitpose(tiny_models["vitpose"]))


@pytest.mark.skipif(bool(missing_models()), reason="BlazePose models not installed (scripts/setup.sh)")
def test_blazepose_composes_with_the_refiners(tiny_models, tmp_path, body):
    """``blazepose+vitpose+sam``: the refiners prompt with the boxes of BlazePose's masks."""
    import cv2

    from multithumbs.perception import load_perception
    from multithumbs.synth.files import write_video
    from multithumbs.types import Shots

    frame = cv2.cvtColor(cv2.imread(str(Path(__file__).parent / "fixtures" / "s09_frame63.png")), cv2.COLOR_BGR2RGB)
    path = write_video(tmp_path / "still.mp4", np.stack([frame] * 8), 24.0)
    shots = Shots(np.array([], np.int64), 24.0, 8, np.zeros(8), "given")
    plain = load_perception("blazepose", path, shots, body=body, appearance=False)
    spec = f"blazepose+vitpose:{tiny_models['vitpose']}+sam:{tiny_models['sam']}"
    refined = load_perception(spec, path, shots, body=body, appearance=False)
    assert plain[0].num_people >= 1 and refined[0].num_people == plain[0].num_people
    seen = plain[0].valid
    assert not np.array_equal(refined[0].keypoints2d[seen], plain[0].keypoints2d[seen])  # ViTPose's now
    np.testing.assert_array_equal(refined[0].transl, plain[0].transl)  # the bodies stay BlazePose's
