#!/usr/bin/env python3
"""A wider learned detector computing the same function (Net2WiderNet, Chen et al. 2016):
each layer's channels grown `factor` times, every added channel a copy of an existing one,
the copies' outgoing weights split unevenly (10 % noise, seeded) so that training can tell
them apart. For docs/EXPERIMENTS.md "A wider network"; not used by the shipped model.

    roadtrack train --detector --average models/detector.onnx models/detector.onnx \
        -o /tmp/base.onnx --weights-out base.json      # the shipped weights as JSON
    python3 scripts/widen_detector.py base.json wide.json 1.5 0
    roadtrack train --detector --init wide.json --steps 6000 --seed 4 --sim-seed-base 14000 \
        --learning-rate 3e-4 -o wide_raw.onnx           # (the CLI's `learn` feature)

The widened network's boxes equal the shipped model's to the float rounding (checked on
five frames: scores within 1e-6). Needs numpy.
"""

import json
import sys

import numpy as np

# The layers in CenterNetShape::layers order: name, kind (conv / deconv), kernel side, the
# channel group of its input and of its output. Layers whose outputs are added (conv3 and
# up2 at stride 4, conv5 and up1 at stride 8) share one group, so the copies line up.
LAYERS = [
    ("conv1", "conv", 3, None, "a"),
    ("conv2", "conv", 3, "a", "b"),
    ("conv3", "conv", 3, "b", "c"),
    ("conv4", "conv", 3, "c", "d"),
    ("conv5", "conv", 3, "d", "e"),
    ("conv6", "conv", 3, "e", "f"),
    ("conv7", "conv", 3, "f", "g"),
    ("up1", "deconv", 2, "g", "e"),
    ("up2", "deconv", 2, "e", "c"),
    ("head", "conv", 1, "c", "h"),
    ("heat", "conv", 1, "h", None),
    ("box", "conv", 1, "h", None),
]
WIDTH = {"a": "c1", "b": "c2", "c": "c2", "d": "c3", "e": "c3", "f": "c4", "g": "c4", "h": "head"}
OUTPUTS = 4  # heat-map classes, and box values


def widen(net, factor, seed):
    rng = np.random.default_rng(seed)
    old = net["shape"]
    new = {k: int(round(v * factor)) for k, v in old.items()}
    # Each group's new channel -> the old channel it copies (the old ones first, in place).
    copy = {
        g: np.array(list(range(old[k])) + list(rng.integers(0, old[k], new[k] - old[k])))
        for g, k in WIDTH.items()
    }
    # The share of an old channel's outgoing weight each of its copies takes: uneven, so that
    # training can tell the copies apart, and summing to one, so the function is unchanged.
    share = {}
    for g, src in copy.items():
        sh = np.zeros(len(src))
        for i in range(old[WIDTH[g]]):
            at = np.where(src == i)[0]
            r = 1.0 + 0.1 * rng.standard_normal(len(at))
            sh[at] = r / r.sum()
        share[g] = sh
    layers = []
    for weights, (name, kind, k, gin, gout) in zip(net["layers"], LAYERS):
        cin = 3 if gin is None else old[WIDTH[gin]]
        cout = OUTPUTS if gout is None else old[WIDTH[gout]]
        w = np.array(weights["weight"], dtype=np.float64)
        w = w.reshape((cout, cin, k, k) if kind == "conv" else (cin, cout, k, k))
        b = np.array(weights["bias"], dtype=np.float64)
        out = copy[gout] if gout else np.arange(cout)
        inp = copy[gin] if gin else np.arange(cin)
        sh = share[gin] if gin else np.ones(cin)
        if kind == "conv":
            w = w[out][:, inp] * sh[None, :, None, None]
        else:
            w = w[inp][:, out] * sh[:, None, None, None]
        layers.append({
            "weight": [float(x) for x in w.astype(np.float32).ravel()],
            "bias": [float(x) for x in b[out].astype(np.float32)],
        })
    return {"shape": new, "layers": layers, "preprocessing": net["preprocessing"]}


def main():
    if len(sys.argv) != 5:
        sys.exit("usage: widen_detector.py IN.json OUT.json FACTOR SEED")
    src, dst, factor, seed = sys.argv[1], sys.argv[2], float(sys.argv[3]), int(sys.argv[4])
    with open(src) as f:
        net = json.load(f)
    wide = widen(net, factor, seed)
    with open(dst, "w") as f:
        json.dump(wide, f)
    print(wide["shape"])


if __name__ == "__main__":
    main()
