"""BlazePose's pre- and post-processing written in the project, checked against MediaPipe itself.

``fixtures/blazepose_reference.npz`` holds what MediaPipe 0.10.21's own pose solution
(``mediapipe.solutions.pose.Pose(static_image_mode=True, model_complexity=1)``, which runs the graph
mediapipe/modules/pose_landmark/pose_landmark_cpu.pbtxt) gives on a rendered frame (image 0,
``fixtures/s09_frame63.png``) and on frames 50, 120, 170 and 230 of OpenCV's ``Megamind.avi`` (images 1-4);
``fixtures/make_blazepose_reference.py`` made it in a separate venv holding the official wheel.
"""

from pathlib import Path

import cv2
import numpy as np
import pytest

from multithumbs.errors import InputError
from multithumbs.perception import blazepose as bp
from multithumbs.perception.blazepose_models import MODEL_FILES, check_models, install_models, missing_models

FIXTURES = Path(__file__).parent / "fixtures"
MEGAMIND_FRAMES = (50, 120, 170, 230)


def test_anchors_follow_the_ssd_layout():
    anchors = bp.ssd_anchors()
    assert anchors.shape == (2254, 2)
    # stride 8: 28x28 cells, 2 anchors each, row-major from the top-left cell
    np.testing.assert_allclose(anchors[0], [0.5 / 28, 0.5 / 28])
    np.testing.assert_allclose(anchors[2], [1.5 / 28, 0.5 / 28])
    # the three stride-32 layers share one 7x7 grid with 6 anchors per cell
    np.testing.assert_allclose(anchors[-1], [6.5 / 7, 6.5 / 7])
    assert len(np.unique(anchors[-6:], axis=0)) == 1


@pytest.mark.parametrize("direction", [(0, -1), (1, 0), (0, 1), (-1, -1)])
def test_roi_puts_the_size_point_straight_above_the_centre(direction):
    centre = np.array([300.0, 200.0])
    point = centre + 50 * np.array(direction) / np.hypot(*direction)
    roi = bp.roi_from_points(centre, point)
    assert roi.size == pytest.approx(2 * 50 * bp.ROI_SCALE)
    matrix = bp._crop_matrix(roi)
    in_crop = matrix @ np.append(point, 1.0)
    centre_in_crop = matrix @ np.append(centre, 1.0)
    np.testing.assert_allclose(centre_in_crop, [bp.LANDMARK_SIZE / 2] * 2, atol=1e-3)
    assert in_crop[0] == pytest.approx(bp.LANDMARK_SIZE / 2, abs=1e-3)
    assert in_crop[1] < bp.LANDMARK_SIZE / 2


def test_weighted_nms_merges_overlapping_detections():
    raw = np.zeros((2254, 12), np.float32)
    logits = np.full(2254, -20.0, np.float32)
    # two anchors of the same cell say nearly the same box; one far anchor says another
    raw[[0, 1, 1500], 2:4] = 20.0
    raw[1, 0] = 2.0
    logits[[0, 1, 1500]] = [3.0, 1.0, 2.0]
    found = bp.decode_detections(raw, logits, scale=1.0, offset=np.zeros(2))
    assert len(found) == 2
    assert found[0].score == pytest.approx(1 / (1 + np.exp(-3.0)))
    weights = 1 / (1 + np.exp(-np.array([3.0, 1.0])))
    expected_x = (bp.ssd_anchors()[0, 0] * 224 + weights[1] * 2.0 / weights.sum())
    assert found[0].face_box[[0, 2]].mean() == pytest.approx(expected_x, abs=1e-6)


def test_heatmap_refinement_moves_to_the_peak_and_ignores_weak_maps():
    heatmap = np.full((64, 64, 2), -10.0, np.float32)
    heatmap[30, 21, 0] = 10.0  # a sharp peak one cell from landmark 0
    points = np.array([[20.5 / 64, 30.5 / 64], [0.5, 0.5]])
    out = bp.refine_from_heatmap(points, heatmap)
    np.testing.assert_allclose(out[0], [21 / 64, 30 / 64], atol=2e-3)
    np.testing.assert_array_equal(out[1], points[1])  # peak below 0.5: unchanged


def test_missing_models_are_a_one_line_error(tmp_path):
    with pytest.raises(InputError, match=r"pose_detection.tflite.*install with"):
        check_models(tmp_path)
    (tmp_path / "pose_detection.tflite").write_bytes(b"not a model")
    assert set(missing_models(tmp_path)) == set(MODEL_FILES)


def test_install_refuses_a_wheel_with_other_bytes(tmp_path):
    import zipfile

    wheel = tmp_path / "mediapipe-0.10.21-py3-none-any.whl"
    with zipfile.ZipFile(wheel, "w") as archive:
        for member, _ in MODEL_FILES.values():
            archive.writestr(member, b"other bytes")
    with pytest.raises(InputError, match="SHA-256 differs"):
        install_models(tmp_path / "models", wheel)
    assert not any((tmp_path / "models").glob("*.tflite"))


@pytest.fixture(scope="module")
def model():
    if missing_models():
        pytest.skip("BlazePose models not installed (scripts/setup.sh)")
    from multithumbs.perception.blazepose_models import BlazePose

    return BlazePose(num_threads=1)


@pytest.fixture(scope="module")
def reference():
    return np.load(FIXTURES / "blazepose_reference.npz")


def compare(model, image: np.ndarray, reference, i: int) -> dict[str, float]:
    h, w = image.shape[:2]
    detections = model.detect(image, min_score=0.5)
    assert detections, f"image {i}: no detection where MediaPipe found a pose"
    found = model.landmarks(image, bp.roi_from_detection(detections[0]))
    expected = reference[f"landmarks_{i}"]
    pixels = np.linalg.norm(found.image[:33, :2] - expected[:, :2] * [w, h], axis=1)
    return {"presence": found.presence, "median_px": float(np.median(pixels)),
            "visibility": float(np.abs(found.image[:33, 3] - expected[:, 3]).max()),
            "world_m": float(np.abs(found.world - reference[f"world_{i}"]).max()),
            "mask": float(np.abs(found.segmentation - reference[f"mask_{i}"] / 255.0).mean())}


def test_landmarks_match_mediapipe_on_a_rendered_frame(model, reference):
    image = cv2.cvtColor(cv2.imread(str(FIXTURES / "s09_frame63.png")), cv2.COLOR_BGR2RGB)
    assert bool(reference["found_0"])
    diff = compare(model, image, reference, 0)
    assert diff["presence"] >= 0.5
    assert diff["median_px"] < 1.0
    assert diff["visibility"] < 0.02
    assert diff["world_m"] < 0.01
    assert diff["mask"] < 0.01


@pytest.mark.slow
def test_landmarks_match_mediapipe_on_real_footage(model, reference, opencv_samples):
    from multithumbs.video import read_frames

    frames = read_frames(opencv_samples / "Megamind.avi", list(MEGAMIND_FRAMES))
    for i, image in enumerate(frames, start=1):
        diff = compare(model, image, reference, i)
        # MediaPipe's detector input is resampled by its own warp; a few pixels on people ~400 px tall.
        assert diff["median_px"] < 4.0, (i, diff)
        assert diff["world_m"] < 0.03, (i, diff)
        assert diff["mask"] < 0.02, (i, diff)
