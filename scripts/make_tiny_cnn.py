#!/usr/bin/env python3
"""Writes the tiny ONNX classifier used by roadtrack's CNN tests, and its reference outputs.

Regenerate (not run in CI; the Rust tests only read the committed files):

    python3 -m venv /tmp/cnnvenv && /tmp/cnnvenv/bin/pip install onnx onnxruntime numpy
    /tmp/cnnvenv/bin/python scripts/make_tiny_cnn.py

Outputs, in crates/roadtrack/tests/fixtures/:
  tiny_classifier.onnx       N×3×32×16 input (H=32, W=16) → 2 class probabilities (softmax)
  tiny_classifier_ref.json   the input formula, and onnxruntime's outputs for it

Graph (valid, unpadded convolutions, so a fully convolutional pass over a whole frame gives
exactly the per-window outputs; see docs/CNN.md "Dense mode"):
  Conv3×3(3→4) → Relu → MaxPool2 → Conv3×3(4→8) → Relu → MaxPool2 → GlobalAveragePool
  → Flatten → Gemm(8→2) → Softmax
Weights are seeded (numpy default_rng(7)), so the file is reproducible byte for byte.
"""
import json
import os

import numpy as np
import onnx
from onnx import TensorProto, helper, numpy_helper

HERE = os.path.dirname(os.path.abspath(__file__))
OUT = os.path.join(HERE, "..", "crates", "roadtrack-cnn", "tests", "fixtures")
H, W = 32, 16
BATCH = 3


def reference_input(n):
    """Deterministic input the Rust test rebuilds: x[i] = ((i*37 + 11) % 101) / 50 - 1."""
    i = np.arange(n * 3 * H * W, dtype=np.int64)
    return (((i * 37 + 11) % 101) / 50.0 - 1.0).astype(np.float32).reshape(n, 3, H, W)


def main():
    rng = np.random.default_rng(7)

    def w(*shape, fan_in):
        return (rng.standard_normal(shape) * np.sqrt(2.0 / fan_in)).astype(np.float32)

    inits = [
        numpy_helper.from_array(w(4, 3, 3, 3, fan_in=27), "conv1.w"),
        numpy_helper.from_array((rng.standard_normal(4) * 0.1).astype(np.float32), "conv1.b"),
        numpy_helper.from_array(w(8, 4, 3, 3, fan_in=36), "conv2.w"),
        numpy_helper.from_array((rng.standard_normal(8) * 0.1).astype(np.float32), "conv2.b"),
        numpy_helper.from_array(w(2, 8, fan_in=8), "fc.w"),
        numpy_helper.from_array((rng.standard_normal(2) * 0.1).astype(np.float32), "fc.b"),
    ]
    nodes = [
        helper.make_node("Conv", ["input", "conv1.w", "conv1.b"], ["c1"], kernel_shape=[3, 3]),
        helper.make_node("Relu", ["c1"], ["r1"]),
        helper.make_node("MaxPool", ["r1"], ["p1"], kernel_shape=[2, 2], strides=[2, 2]),
        helper.make_node("Conv", ["p1", "conv2.w", "conv2.b"], ["c2"], kernel_shape=[3, 3]),
        helper.make_node("Relu", ["c2"], ["r2"]),
        helper.make_node("MaxPool", ["r2"], ["p2"], kernel_shape=[2, 2], strides=[2, 2]),
        helper.make_node("GlobalAveragePool", ["p2"], ["gap"]),
        helper.make_node("Flatten", ["gap"], ["flat"], axis=1),
        helper.make_node("Gemm", ["flat", "fc.w", "fc.b"], ["logits"], transB=1),
        helper.make_node("Softmax", ["logits"], ["probabilities"], axis=1),
    ]
    graph = helper.make_graph(
        nodes,
        "tiny_classifier",
        [helper.make_tensor_value_info("input", TensorProto.FLOAT, ["N", 3, H, W])],
        [helper.make_tensor_value_info("probabilities", TensorProto.FLOAT, ["N", 2])],
        inits,
    )
    model = helper.make_model(
        graph,
        producer_name="roadtrack scripts/make_tiny_cnn.py",
        opset_imports=[helper.make_opsetid("", 13)],
    )
    model.ir_version = 8
    onnx.checker.check_model(model)
    os.makedirs(OUT, exist_ok=True)
    path = os.path.join(OUT, "tiny_classifier.onnx")
    onnx.save(model, path)

    import onnxruntime as ort

    sess = ort.InferenceSession(path, providers=["CPUExecutionProvider"])
    x = reference_input(BATCH)
    (probs,) = sess.run(None, {"input": x})
    ref = {
        "command": "python3 scripts/make_tiny_cnn.py",
        "onnxruntime": ort.__version__,
        "input_shape": [BATCH, 3, H, W],
        "input_formula": "x[i] = ((i*37 + 11) % 101) / 50 - 1, i = flat NCHW index",
        "output": [[float(v) for v in row] for row in probs],
    }
    with open(os.path.join(OUT, "tiny_classifier_ref.json"), "w") as f:
        json.dump(ref, f, indent=1)
        f.write("\n")
    print(path, os.path.getsize(path), "bytes")
    print(probs)


if __name__ == "__main__":
    main()
