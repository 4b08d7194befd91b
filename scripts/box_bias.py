#!/usr/bin/env python3
"""Where the learned detector's boxes go wrong, per class and orientation
(docs/EXPERIMENTS.md "Box errors by class"). On the simulator's sequences (seed 0 by
default, never used in training) it runs `roadtrack detect --detector cnn`, matches
detections to the truth (visibility ≥ 0.5) greedily by IoU ≥ 0.3 whatever the class, and
prints, per truth class and orientation ("wide": truth box wider than tall), the truth
count, the share matched at IoU ≥ 0.3 and at ≥ 0.5, the matched boxes' mean IoU, and their
signed mean errors: ln(w / w_true), ln(h / h_true) and the centre offset in px. A
systematic sign (every box too tall, say) is a bias the decoding or the training made; a
spread around zero is noise.

    python3 scripts/box_bias.py --roadtrack $CARGO_TARGET_DIR/release/roadtrack \\
        [--frames 300] [--seed 0] [--work /tmp/detcmp] [--cnn-args '--no-flip']

Run from the repository root. Not part of the test suite; needs only Python 3.
"""
import argparse
import math
import os
import subprocess
import sys
from collections import defaultdict

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from detection_compare import (  # noqa: E402
    CLASSES, add_sequence_arguments, greedy_match, read_gt, read_ours, sequence)


def errors(gt, dets, n_frames):
    """Per (class name, orientation): [truth count, matched ≥ 0.3, matched ≥ 0.5, Σ IoU,
    Σ ln w ratio, Σ ln h ratio, Σ dx, Σ dy] over the frames."""
    acc = defaultdict(lambda: [0, 0, 0, 0.0, 0.0, 0.0, 0.0, 0.0])
    for frame in range(1, n_frames + 1):
        g = [t for t in gt.get(frame, []) if t[3] >= 0.5]
        d = dets.get(frame, [])
        match = {i: (j, v) for i, j, v in greedy_match([t[1] for t in g], d, 0.3)}
        for i, (_, (gx, gy, gw, gh), cls, _) in enumerate(g):
            key = (CLASSES.get(cls, str(cls)), "wide" if gw >= gh else "tall")
            a = acc[key]
            a[0] += 1
            if i not in match:
                continue
            j, v = match[i]
            dx, dy, dw, dh = d[j]
            a[1] += 1
            a[2] += v >= 0.5
            a[3] += v
            a[4] += math.log(dw / gw)
            a[5] += math.log(dh / gh)
            a[6] += (dx + dw / 2) - (gx + gw / 2)
            a[7] += (dy + dh / 2) - (gy + gh / 2)
    return acc


def main():
    ap = argparse.ArgumentParser()
    add_sequence_arguments(ap, seed=0)
    ap.add_argument("--cnn-args", default="", help="extra flags for --detector cnn")
    a = ap.parse_args()
    os.makedirs(a.work, exist_ok=True)
    print("| scene | view | class | orientation | truth | matched ≥ 0.3 | ≥ 0.5 | mean IoU "
          "| ln(w / w_true) | ln(h / h_true) | dx (px) | dy (px) |")
    print("| --- | --- | --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
    for scene in a.scenes.split(","):
        for view in a.views.split(","):
            seq = sequence(a, scene, view)
            out = f"{seq}/det_cnn_bias.csv"
            subprocess.run([a.roadtrack, "-q", "detect", seq, "-o", out, "--detector", "cnn",
                            "--end", str(a.frames), *a.cnn_args.split()], check=True)
            acc = errors(read_gt(seq), read_ours(out), a.frames)
            for (cls, orient), (n, m3, m5, s_iou, lw, lh, dx, dy) in sorted(acc.items()):
                if n == 0:
                    continue
                if m3 == 0:
                    cells = ["0.00", "0.00"] + ["–"] * 5
                else:
                    cells = [f"{m3 / n:.2f}", f"{m5 / n:.2f}", f"{s_iou / m3:.2f}",
                             f"{lw / m3:+.2f}", f"{lh / m3:+.2f}", f"{dx / m3:+.1f}",
                             f"{dy / m3:+.1f}"]
                print(f"| {scene} | {view} | {cls} | {orient} | {n} | " + " | ".join(cells)
                      + " |", flush=True)


if __name__ == "__main__":
    main()
