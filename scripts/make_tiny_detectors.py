#!/usr/bin/env python3
"""Writes the tiny ONNX "detectors" used by roadtrack's `--detector onnx` tests.

Regenerate (not run in CI; the Rust tests only read the committed files):

    python3 -m venv /tmp/onnxvenv && /tmp/onnxvenv/bin/pip install onnx numpy onnxruntime
    /tmp/onnxvenv/bin/python scripts/make_tiny_detectors.py

Each model takes a 1×3×64×64 image and returns the same fixed boxes whatever the image
(output = constant + 0 · mean(input), so the input is used and the expected boxes are
known exactly), in one output layout each. Outputs, in crates/roadtrack-cnn/tests/fixtures/:

  tiny_yolo.onnx      [1, 6, 84]            cx, cy, w, h (input px), 80 COCO class scores
  tiny_yolo_t.onnx    [1, 84, 6]            the same, transposed (ultralytics' export)
  tiny_yolox.onnx     [1, 7, 85]            cx, cy, w, h, objectness, 80 class scores
  tiny_detr.onnx      logits [1, 7, 80] + pred_boxes [1, 7, 4] (normalised cx, cy, w, h)
  tiny_unknown.onnx   [1, 2, 3, 4]          no detector layout (an error case)

The boxes (input px; score = objectness × class score for YOLOX, sigmoid of the logit
for DETR):

  a  (32, 32, 16, 8)  person 0.9    (YOLOX: objectness 0.9 × class 1.0)
  b  (33, 32, 16, 8)  person 0.8    overlaps a (IoU 0.88): removed by NMS
  c  (32, 32, 16, 8)  car    0.7    same box as a, another class: kept
  d  (10, 20,  8, 8)  truck  0.2    below the default threshold 0.25
  e  (50, 40,  8, 8)  dog    0.95   no roadtrack class: dropped by default
  f  (60, 44, 16, 8)  bus    0.6    sticks out of the input: clipped
  g  (20, 40,  8, 8)  car    obj 0.1 × class 1.0 (YOLOX only; DETR: an empty query)
"""
import os

import numpy as np
import onnx
import onnxruntime as ort
from onnx import TensorProto, helper, numpy_helper

HERE = os.path.dirname(os.path.abspath(__file__))
OUT = os.path.join(HERE, "..", "crates", "roadtrack-cnn", "tests", "fixtures")
SIDE = 64
C = 80
LOW = 0.01  # every other class's score

# (cx, cy, w, h, class, score)
BOXES = [
    (32, 32, 16, 8, 0, 0.9),
    (33, 32, 16, 8, 0, 0.8),
    (32, 32, 16, 8, 2, 0.7),
    (10, 20, 8, 8, 7, 0.2),
    (50, 40, 8, 8, 16, 0.95),
    (60, 44, 16, 8, 5, 0.6),
]


def yolo_rows():
    rows = np.full((len(BOXES), 4 + C), LOW, dtype=np.float32)
    for r, (cx, cy, w, h, cls, s) in enumerate(BOXES):
        rows[r, :4] = (cx, cy, w, h)
        rows[r, 4 + cls] = s
    return rows


def yolox_rows():
    rows = np.full((len(BOXES) + 1, 5 + C), LOW, dtype=np.float32)
    for r, (cx, cy, w, h, cls, s) in enumerate(BOXES):
        rows[r, :4] = (cx, cy, w, h)
        if r == 0:
            rows[r, 4], rows[r, 5 + cls] = 0.9, 1.0
        else:
            rows[r, 4], rows[r, 5 + cls] = 1.0, s
    rows[-1, :4] = (20, 40, 8, 8)
    rows[-1, 4], rows[-1, 5 + 2] = 0.1, 1.0
    return rows


def logit(p):
    return float(np.log(p / (1.0 - p)))


def detr_outputs():
    q = len(BOXES) + 1
    boxes = np.full((q, 4), 0.5, dtype=np.float32)
    logits = np.full((q, C), logit(LOW), dtype=np.float32)
    for r, (cx, cy, w, h, cls, s) in enumerate(BOXES):
        boxes[r] = np.array((cx, cy, w, h), dtype=np.float32) / SIDE
        logits[r, cls] = logit(s)
    # The last query finds nothing: every class at LOW.
    return logits[None], boxes[None]


def constant_model(name, outputs):
    """A graph whose outputs are `value + 0 · mean(input)` for each (name, value)."""
    nodes = [
        helper.make_node("ReduceMean", ["images"], ["mean"], keepdims=0),
        helper.make_node("Mul", ["mean", "zero"], ["nothing"]),
    ]
    inits = [numpy_helper.from_array(np.zeros((), dtype=np.float32), "zero")]
    infos = []
    for out_name, value in outputs:
        inits.append(numpy_helper.from_array(value.astype(np.float32), out_name + ".value"))
        nodes.append(helper.make_node("Add", [out_name + ".value", "nothing"], [out_name]))
        infos.append(helper.make_tensor_value_info(out_name, TensorProto.FLOAT, list(value.shape)))
    graph = helper.make_graph(
        nodes,
        name,
        [helper.make_tensor_value_info("images", TensorProto.FLOAT, [1, 3, SIDE, SIDE])],
        infos,
        inits,
    )
    model = helper.make_model(
        graph,
        producer_name="roadtrack scripts/make_tiny_detectors.py",
        opset_imports=[helper.make_opsetid("", 13)],
    )
    model.ir_version = 8
    onnx.checker.check_model(model)
    path = os.path.join(OUT, name + ".onnx")
    onnx.save(model, path)
    # Check with onnxruntime that the outputs are the constants.
    sess = ort.InferenceSession(path, providers=["CPUExecutionProvider"])
    got = sess.run(None, {"images": np.random.default_rng(1).random((1, 3, SIDE, SIDE), dtype=np.float32)})
    for (out_name, value), g in zip(outputs, got):
        assert g.shape == value.shape and np.array_equal(g, value.astype(np.float32)), out_name
    print(f"{path}: {os.path.getsize(path)} bytes, outputs {[v.shape for _, v in outputs]}")


def main():
    os.makedirs(OUT, exist_ok=True)
    rows = yolo_rows()
    constant_model("tiny_yolo", [("output0", rows[None])])
    constant_model("tiny_yolo_t", [("output0", rows.T[None])])
    constant_model("tiny_yolox", [("output", yolox_rows()[None])])
    logits, boxes = detr_outputs()
    constant_model("tiny_detr", [("logits", logits), ("pred_boxes", boxes)])
    constant_model("tiny_unknown", [("output", np.zeros((1, 2, 3, 4), dtype=np.float32))])


if __name__ == "__main__":
    main()
