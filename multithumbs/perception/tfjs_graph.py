"""Run a TensorFlow.js graph model (``model.json`` + its weight files) with torch, for the ops CNN detectors use.

The format is TensorFlow.js's ``graph-model`` (written by ``tensorflowjs_converter``):

- ``model.json`` holds ``modelTopology``, a TensorFlow ``GraphDef`` in protobuf's JSON mapping (``node``: each
  with ``name``, ``op``, ``input`` and ``attr``), and ``weightsManifest``: groups of ``paths`` (the binary
  files, read one after another as a single buffer) and ``weights``, each ``name``, ``shape``, ``dtype`` and
  an optional ``quantization`` (``dtype`` float16 or uint8 / uint16 with ``scale`` and ``min``), in buffer
  order. Every ``Const`` node's value is the weight of its name;
- an input ``foo:1`` is output 1 of node ``foo``; one starting with ``^`` is a control dependency.

:class:`GraphModel` evaluates the graph in its own layout (NHWC, as TensorFlow does) with one torch op per
node. It knows the ops of the convolutional detectors it is used for (:data:`OPS`) and refuses a graph with
any other at load time, naming them: a model it cannot run fully is never run in part.
"""

from __future__ import annotations

import base64
import json
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F

from multithumbs.errors import InputError

_NUMPY_DTYPES = {"float32": np.float32, "int32": np.int32, "bool": np.bool_, "float16": np.float16,
                 "uint8": np.uint8, "uint16": np.uint16}


def _text(attr: dict) -> str:
    return base64.b64decode(attr["s"]).decode()


def _ints(attr: dict) -> list[int]:
    return [int(i) for i in attr.get("list", {}).get("i", [])]


def read_weights(manifest: list[dict], folder: Path) -> dict[str, np.ndarray]:
    """The weights a ``weightsManifest`` names, dequantized, by name."""
    weights = {}
    for group in manifest:
        try:
            buffer = b"".join((folder / path).read_bytes() for path in group["paths"])
        except OSError as error:
            raise InputError(f"{folder}: cannot read the weight files {group['paths']} ({error})") from None
        offset = 0
        for entry in group["weights"]:
            quant = entry.get("quantization")
            stored = quant["dtype"] if quant else entry["dtype"]
            if stored not in _NUMPY_DTYPES or entry["dtype"] not in _NUMPY_DTYPES:
                raise InputError(f"{folder}: weight {entry['name']!r} has dtype {stored!r}, which this reader does not know")
            count = int(np.prod(entry["shape"], dtype=np.int64))
            size = count * np.dtype(_NUMPY_DTYPES[stored]).itemsize
            if offset + size > len(buffer):
                raise InputError(f"{folder}: weight files end before weight {entry['name']!r} (truncated download?)")
            value = np.frombuffer(buffer, _NUMPY_DTYPES[stored], count, offset).reshape(entry["shape"])
            offset += size
            if quant and stored in ("uint8", "uint16"):
                # q * scale + min in double, an int32 weight rounded, as tfjs-core's io_utils decodeWeights and
                # tensorflowjs's quantization.dequantize_weights do
                value = value.astype(np.float64) * quant["scale"] + quant["min"]
                if entry["dtype"] == "int32":
                    value = np.round(value)
            weights[entry["name"]] = value.astype(_NUMPY_DTYPES[entry["dtype"]])
        if offset != len(buffer):
            raise InputError(f"{folder}: weight files hold {len(buffer) - offset} bytes beyond the manifest's weights")
    return weights


def _tensor(value: np.ndarray) -> torch.Tensor:
    value = np.asarray(value)
    return torch.from_numpy(value.astype(np.int64) if value.dtype.kind in "iu" else value.astype(np.float32))


def _padding(x: torch.Tensor, attr: dict, kernel: tuple[int, int], strides: tuple[int, int],
             dilations: tuple[int, int] = (1, 1), value: float = 0.0) -> torch.Tensor:
    """``x`` (N, C, H, W) padded as TensorFlow's SAME (extra row/column at the end) or EXPLICIT asks; VALID: as is."""
    mode = _text(attr["padding"])
    if mode == "VALID":
        return x
    if mode == "EXPLICIT":
        p = _ints(attr["explicit_paddings"])  # NHWC pairs
        return F.pad(x, (p[4], p[5], p[2], p[3]), value=value)
    pads = []
    for size, k, s, d in zip(x.shape[2:], kernel, strides, dilations):
        total = max((-(-size // s) - 1) * s + (k - 1) * d + 1 - size, 0)
        pads.append((total // 2, total - total // 2))
    return F.pad(x, (pads[1][0], pads[1][1], pads[0][0], pads[0][1]), value=value)


def _conv2d(x, w, attr, depthwise=False):
    nchw = x.permute(0, 3, 1, 2)
    strides, dilations = _ints(attr["strides"])[1:3], (_ints(attr.get("dilations", {})) or [1, 1, 1, 1])[1:3]
    kernel = tuple(w.shape[:2])
    nchw = _padding(nchw, attr, kernel, tuple(strides), tuple(dilations))
    if depthwise:  # filter (H, W, C, multiplier)
        weight = w.permute(2, 3, 0, 1).reshape(-1, 1, *kernel)
        groups = nchw.shape[1]
    else:  # filter (H, W, C_in / groups, C_out)
        weight = w.permute(3, 2, 0, 1)
        groups = nchw.shape[1] // w.shape[2]
    out = F.conv2d(nchw, weight, stride=strides, dilation=dilations, groups=groups)
    return out.permute(0, 2, 3, 1)


def _max_pool(x, attr):
    nchw = x.permute(0, 3, 1, 2)
    kernel, strides = tuple(_ints(attr["ksize"])[1:3]), tuple(_ints(attr["strides"])[1:3])
    nchw = _padding(nchw, attr, kernel, strides, value=float("-inf"))
    return F.max_pool2d(nchw, kernel, strides).permute(0, 2, 3, 1)


def _resize_bilinear(x, size, attr):
    if attr.get("align_corners", {}).get("b", False) or not attr.get("half_pixel_centers", {}).get("b", False):
        raise InputError("ResizeBilinear: only half_pixel_centers=True, align_corners=False is supported")
    out = F.interpolate(x.permute(0, 3, 1, 2), size=tuple(int(v) for v in size), mode="bilinear", align_corners=False)
    return out.permute(0, 2, 3, 1)


def _sparse_to_dense(indices, shape, values, default):
    out = torch.full(tuple(int(v) for v in shape.reshape(-1)), default.item(), dtype=values.dtype)
    if indices.numel():
        out[tuple(indices.reshape(indices.shape[0], -1).T)] = values
    return out


def _split_v(x, sizes, axis):
    sizes = [int(s) for s in sizes]
    if -1 in sizes:
        sizes[sizes.index(-1)] = x.shape[int(axis)] - (sum(sizes) + 1)
    return list(torch.split(x, sizes, dim=int(axis)))


OPS = {
    "Identity": lambda a, x: x,
    "Add": lambda a, x, y: x + y,
    "AddV2": lambda a, x, y: x + y,
    "Sub": lambda a, x, y: x - y,
    "Mul": lambda a, x, y: x * y,
    "Sigmoid": lambda a, x: torch.sigmoid(x),
    "Relu": lambda a, x: torch.relu(x),
    "Relu6": lambda a, x: torch.clamp(x, 0, 6),
    "LeakyRelu": lambda a, x: F.leaky_relu(x, a.get("alpha", {}).get("f", 0.2)),
    "Transpose": lambda a, x, perm: x.permute(*[int(p) for p in perm]),
    "Reshape": lambda a, x, shape: x.reshape(*[int(s) for s in shape]),
    "Pad": lambda a, x, p: F.pad(x, tuple(int(v) for v in p.flip(0).reshape(-1))),
    "PadV2": lambda a, x, p, c: F.pad(x, tuple(int(v) for v in p.flip(0).reshape(-1)), value=float(c)),
    "ConcatV2": lambda a, *xs: torch.cat(xs[:-1], dim=int(xs[-1])),
    "SplitV": lambda a, x, sizes, axis: _split_v(x, sizes, axis),
    "Conv2D": lambda a, x, w: _conv2d(x, w, a),
    "DepthwiseConv2dNative": lambda a, x, w: _conv2d(x, w, a, depthwise=True),
    "MaxPool": lambda a, x: _max_pool(x, a),
    "ResizeBilinear": lambda a, x, size: _resize_bilinear(x, size, a),
    "SparseToDense": lambda a, i, shape, v, d: _sparse_to_dense(i, shape, v, d),
}
"""The ops :class:`GraphModel` runs: ``op -> f(attr, *inputs)`` (an op with several outputs returns a list)."""


def _in_order(nodes: list[dict], path: Path) -> list[dict]:
    """The nodes in an order where each comes after the nodes it reads (a GraphDef need not be sorted)."""
    by_name = {n["name"]: n for n in nodes}
    placed: set[str] = set()
    order: list[dict] = []
    for start in nodes:
        stack = [(start, False)]
        while stack:
            node, expanded = stack.pop()
            if node["name"] in placed:
                continue
            if expanded:
                placed.add(node["name"])
                order.append(node)
                continue
            stack.append((node, True))
            for name in node.get("input", []):
                source = by_name.get(name.lstrip("^").partition(":")[0])
                if source is not None and source["name"] not in placed:
                    if any(s is source and e for s, e in stack):
                        raise InputError(f"{path}: the graph has a cycle through {source['name']!r}")
                    stack.append((source, False))
    return order


class GraphModel:
    """A loaded TensorFlow.js graph model (module docstring).

    Args:
        model_json: the ``model.json``; its weight files are read from beside it.
    """

    def __init__(self, model_json: str | Path):
        path = Path(model_json)
        try:
            spec = json.loads(path.read_text())
            nodes = spec["modelTopology"]["node"]
            manifest = spec["weightsManifest"]
        except (OSError, ValueError, KeyError, TypeError) as error:
            raise InputError(f"{path}: not a TensorFlow.js graph model ({error})") from None
        unknown = sorted({n["op"] for n in nodes} - set(OPS) - {"Const", "Placeholder"})
        if unknown:
            raise InputError(f"{path}: ops this runner does not know: {', '.join(unknown)}")
        weights = read_weights(manifest, path.parent)
        missing = [n["name"] for n in nodes if n["op"] == "Const" and n["name"] not in weights]
        if missing:
            raise InputError(f"{path}: constants without weights: {', '.join(missing[:5])}")
        self.nodes = _in_order([n for n in nodes if n["op"] not in ("Const", "Placeholder")], path)
        self.constants = {name: _tensor(value) for name, value in weights.items()}
        self.inputs = [n["name"] for n in nodes if n["op"] == "Placeholder"]
        self.outputs = sorted(n["name"] for n in nodes if n["op"] == "Identity" and n["name"].startswith("Identity"))

    def __call__(self, feed: dict[str, torch.Tensor], outputs: list[str] | None = None) -> dict[str, torch.Tensor]:
        """The named outputs (default: the graph's ``Identity*`` nodes) for a feed of its inputs by name."""
        values: dict[str, object] = dict(self.constants)
        values.update(feed)
        with torch.no_grad():
            for node in self.nodes:
                args = [self._value(values, name) for name in node.get("input", []) if not name.startswith("^")]
                values[node["name"]] = OPS[node["op"]](node.get("attr", {}), *args)
        return {name: self._value(values, name) for name in (outputs or self.outputs)}

    @staticmethod
    def _value(values: dict, name: str):
        node, _, index = name.partition(":")
        value = values[node]
        return value[int(index or 0)] if isinstance(value, list) else value


__all__ = ["GraphModel", "read_weights", "OPS"]
