"""The TensorFlow.js graph-model runner against models written by tensorflowjs's own converter and TensorFlow's
outputs for them.

The fixtures in ``fixtures/tfjs_graph/`` were made by ``fixtures/tfjs_graph/make_fixture.py`` (its docstring
says how, and with which versions: TensorFlow 2.18.1, tensorflowjs 4.22.0, tfjs-graph-converter 1.6.3) with
the upstream code paths that write the format:

- ``tensorflowjs/converters/tf_saved_model_conversion_v2.py``: ``convert_tf_saved_model`` ->
  ``_convert_tf_saved_model`` -> ``optimize_graph`` (grappler, ``normalize_bias_add``,
  ``fuse_depthwise_conv2d``), ``extract_weights`` / ``extract_const_nodes`` (every ``Const`` node's value
  moved to the weights, under the node's name) and ``write_artifacts`` (``model.json``: ``format``,
  ``signature``, ``modelTopology`` as the GraphDef's JSON mapping, ``weightsManifest``);
- ``tensorflowjs/write_weights.py``: ``write_weights`` (groups' bytes concatenated in manifest order, cut into
  ``groupN-shardKofM.bin`` files), ``_quantize_entry`` and ``_get_weights_manifest_for_group`` (the entry's
  ``dtype`` is the original one; ``quantization`` holds the stored ``dtype`` and, for uint8 / uint16,
  ``scale`` and ``min``);
- ``tensorflowjs/quantization.py``: ``quantize_weights`` / ``dequantize_weights``: value = q * scale + min,
  rounded for an int32 weight (as tfjs-core's ``src/io/io_utils.ts`` ``decodeWeight`` does in JavaScript).

The expected numbers are TensorFlow's, not this runner's: the ``tf.function`` itself for the float32 model;
for the quantized copies, TensorFlow running each converted graph loaded back by tfjs-graph-converter (weights
dequantized by tensorflowjs's ``read_weights``); and tensorflowjs's ``read_weights.read_weights`` for the
weights themselves.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
import torch

from multithumbs.errors import InputError
from multithumbs.perception.tfjs_graph import OPS, GraphModel, read_weights

FIXTURES = Path(__file__).parent / "fixtures" / "tfjs_graph"
TINY_OPS = {"Add", "AddV2", "ConcatV2", "Const", "Conv2D", "DepthwiseConv2dNative", "Identity", "LeakyRelu",
            "MaxPool", "Mul", "Pad", "PadV2", "Placeholder", "Relu", "Relu6", "Reshape", "ResizeBilinear",
            "Sigmoid", "SparseToDense", "SplitV", "Sub", "Transpose"}


@pytest.fixture(scope="module")
def reference():
    return np.load(FIXTURES / "tiny_reference.npz")


def _spec(folder: str) -> dict:
    return json.loads((FIXTURES / folder / "model.json").read_text())


def _run(folder: str, reference) -> dict[str, np.ndarray]:
    """The tiny model's outputs by signature key (scores, distances, scattered)."""
    model = GraphModel(FIXTURES / folder / "model.json")
    out = model({"input_1": torch.from_numpy(reference["input"])})
    nodes = {key: value["name"].partition(":")[0] for key, value in _spec(folder)["signature"]["outputs"].items()}
    assert set(out) == set(nodes.values())
    return {key: out[node].numpy() for key, node in nodes.items()}


def test_the_fixture_is_what_the_converter_wrote(reference):
    spec = _spec("tiny_float32")
    assert spec["format"] == "graph-model" and spec["convertedBy"].startswith("TensorFlow.js Converter v4.22")
    assert {n["op"] for n in spec["modelTopology"]["node"]} == TINY_OPS  # every op of NanoDet's graph and more
    assert TINY_OPS - {"Const", "Placeholder"} <= set(OPS)
    assert json.loads(str(reference["versions"]))["tensorflow"] == "2.18.1"
    # the input is numpy's default_rng(seed) standard normal, so it can be made again from the seed
    again = np.random.default_rng(int(reference["seed"])).standard_normal((1, 3, 32, 32)).astype(np.float32)
    np.testing.assert_array_equal(again, reference["input"])


def test_float32_graph_matches_tensorflow(reference):
    out = _run("tiny_float32", reference)
    for key, value in out.items():
        expected = reference[f"float32_{key}"]
        assert value.shape == expected.shape
        np.testing.assert_allclose(value, expected, rtol=0, atol=1e-5 * max(1.0, np.abs(expected).max()), err_msg=key)
    # the SparseToDense output puts the 128 sigmoid scores at their indices and 0.25 elsewhere
    assert np.isclose(out["scattered"], 0.25).sum() >= 200 - 128


@pytest.mark.parametrize("quantization", ["uint8", "float16"])
def test_quantized_graph_matches_tensorflow_on_the_dequantized_weights(reference, quantization):
    out = _run(f"tiny_{quantization}", reference)
    for key, value in out.items():
        expected = reference[f"converted_{quantization}_{key}"]
        scale = max(1.0, np.abs(expected).max())
        np.testing.assert_allclose(value, expected, rtol=0, atol=1e-5 * scale, err_msg=key)
        # the quantization shows in the outputs, so a reader ignoring it could not pass the check above
        if quantization == "uint8":
            assert np.abs(expected - reference[f"float32_{key}"]).max() > 1e-3 * scale


def test_uint8_quantized_weights_are_q_times_scale_plus_min():
    """tensorflowjs's ``quantization.dequantize_weights`` formula, from the stored bytes and the manifest."""
    spec = _spec("tiny_uint8")
    (group,) = spec["weightsManifest"]
    buffer = b"".join((FIXTURES / "tiny_uint8" / path).read_bytes() for path in group["paths"])
    weights = read_weights(spec["weightsManifest"], FIXTURES / "tiny_uint8")
    originals = read_weights(_spec("tiny_float32")["weightsManifest"], FIXTURES / "tiny_float32")
    offset, quantized = 0, 0
    for entry in group["weights"]:
        quant = entry.get("quantization")
        count = int(np.prod(entry["shape"]))
        if quant is None:
            raw = np.frombuffer(buffer, np.dtype(entry["dtype"]), count, offset)
            offset += raw.nbytes
            np.testing.assert_array_equal(weights[entry["name"]].ravel(), raw)
            continue
        assert quant["dtype"] == "uint8" and entry["dtype"] == "float32"
        q = np.frombuffer(buffer, np.uint8, count, offset)
        offset += count
        expected = (q * quant["scale"] + quant["min"]).astype(np.float32)
        np.testing.assert_array_equal(weights[entry["name"]].ravel(), expected)
        original = originals[entry["name"]].ravel()
        if np.isfinite(original).all():  # each within half a step of the float32 model's weight
            assert np.abs(expected - original).max() <= quant["scale"] / 2 + 1e-6
        quantized += 1
    assert offset == len(buffer) and quantized >= 10


@pytest.mark.parametrize("folder", ["tiny_float32", "tiny_uint8", "tiny_float16", "quantized_int32"])
def test_weights_are_read_as_tensorflowjs_reads_them(folder):
    """Bit for bit what ``tensorflowjs.read_weights.read_weights`` gave, int32 weights quantized to uint8 /
    uint16 included (rounded, not truncated: ``[1, -1, 44]`` stays a shape, not ``[1, -1, 43]``); the
    ``quantized_int32`` manifest also spreads its bytes over two shard files."""
    expected = np.load(FIXTURES / "weights_reference.npz")
    manifest = (_spec(folder)["weightsManifest"] if folder.startswith("tiny")
                else json.loads((FIXTURES / folder / "weights_manifest.json").read_text()))
    weights = read_weights(manifest, FIXTURES / folder)
    names = json.loads(str(expected[f"{folder}/names"]))
    assert sorted(weights) == sorted(names)
    for index, name in enumerate(names):
        value = expected[f"{folder}/{index}"]
        assert weights[name].dtype == value.dtype, name
        np.testing.assert_array_equal(weights[name], value, err_msg=name)
    if folder == "quantized_int32":
        assert len(manifest[0]["paths"]) == 2
        np.testing.assert_array_equal(weights["shape_a_uint8"], [1, -1, 44])
        np.testing.assert_array_equal(weights["shape_b_uint16"], [-1, 7, 300])


# Malformed input: each refused at load with InputError, naming what is wrong.

def _copy(tmp_path: Path, folder: str = "tiny_float32") -> Path:
    target = tmp_path / folder
    shutil.copytree(FIXTURES / folder, target)
    return target / "model.json"


def test_fused_ops_of_the_current_converter_are_refused_at_load_by_name():
    with pytest.raises(InputError, match="FusedDepthwiseConv2dNative, _FusedConv2D"):
        GraphModel(FIXTURES / "fused" / "model.json")


def test_unknown_op_is_refused_at_load_by_name(tmp_path):
    path = _copy(tmp_path)
    spec = json.loads(path.read_text())
    next(n for n in spec["modelTopology"]["node"] if n["op"] == "Relu6")["op"] = "Softplus"
    path.write_text(json.dumps(spec))
    with pytest.raises(InputError, match="ops this runner does not know: Softplus"):
        GraphModel(path)


def test_truncated_weights_are_refused(tmp_path):
    path = _copy(tmp_path)
    shard = path.parent / "group1-shard1of1.bin"
    shard.write_bytes(shard.read_bytes()[:-4])
    with pytest.raises(InputError, match="weight files end before weight"):
        GraphModel(path)


def test_extra_weight_bytes_are_refused(tmp_path):
    path = _copy(tmp_path)
    shard = path.parent / "group1-shard1of1.bin"
    shard.write_bytes(shard.read_bytes() + b"\0\0\0\0")
    with pytest.raises(InputError, match="4 bytes beyond the manifest"):
        GraphModel(path)


def test_missing_weight_file_is_refused(tmp_path):
    path = _copy(tmp_path)
    (path.parent / "group1-shard1of1.bin").unlink()
    with pytest.raises(InputError, match="group1-shard1of1.bin"):
        GraphModel(path)


def test_constant_without_weight_is_refused(tmp_path):
    path = _copy(tmp_path)
    spec = json.loads(path.read_text())
    spec["weightsManifest"][0]["weights"][0]["name"] = "renamed"
    path.write_text(json.dumps(spec))
    with pytest.raises(InputError, match="constants without weights"):
        GraphModel(path)


def test_unknown_weight_dtype_is_refused(tmp_path):
    path = _copy(tmp_path)
    spec = json.loads(path.read_text())
    spec["weightsManifest"][0]["weights"][0]["dtype"] = "complex64"
    path.write_text(json.dumps(spec))
    with pytest.raises(InputError, match="complex64"):
        GraphModel(path)


@pytest.mark.parametrize("text", [
    "{not json",
    "[]",
    '{"format": "layers-model", "modelTopology": {"class_name": "Sequential", "config": {}}, "weightsManifest": []}',
    '{"format": "graph-model", "modelTopology": {"node": []}}',
])
def test_not_a_graph_model_is_refused(tmp_path, text):
    path = tmp_path / "model.json"
    path.write_text(text)
    with pytest.raises(InputError, match="not a TensorFlow.js graph model"):
        GraphModel(path)


def test_missing_model_json_is_refused(tmp_path):
    with pytest.raises(InputError, match="not a TensorFlow.js graph model"):
        GraphModel(tmp_path / "model.json")


def test_cycle_is_refused(tmp_path):
    path = _copy(tmp_path)
    spec = json.loads(path.read_text())
    nodes = {n["name"]: n for n in spec["modelTopology"]["node"]}
    first = nodes["StatefulPartitionedCall/transpose"]  # reads the Pad of the input; make it read a later node
    first["input"][0] = "StatefulPartitionedCall/LeakyRelu"
    path.write_text(json.dumps(spec))
    with pytest.raises(InputError, match="cycle"):
        GraphModel(path)
