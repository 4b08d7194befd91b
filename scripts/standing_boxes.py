#!/usr/bin/env python3
"""How well the vehicle boxes of detection files sit on standing and on moving vehicles
(docs/EXPERIMENTS.md "Vehicles the background model has absorbed").

    python scripts/standing_boxes.py SEQ A.csv [B.csv …]

SEQ is a `roadtrack simulate` folder (its truth.csv); each CSV a `roadtrack detect` output.
For the truth's cars, lorries and buses at least half visible, split by speed (standing:
under 0.1 m/s), prints how many there are and the share whose best-overlapping detection
(any class) reaches IoU 0.5 and 0.75. Not part of the test suite; needs numpy.
"""
import csv
import sys
from collections import defaultdict

import numpy as np

VEHICLES = ("car", "truck", "bus")


def iou(a, b):
    iw = max(0.0, min(a[0] + a[2], b[0] + b[2]) - max(a[0], b[0]))
    ih = max(0.0, min(a[1] + a[3], b[1] + b[3]) - max(a[1], b[1]))
    inter = iw * ih
    return inter / (a[2] * a[3] + b[2] * b[3] - inter)


def main(seq, files):
    truth = defaultdict(list)
    with open(f"{seq}/truth.csv") as f:
        for r in csv.DictReader(f):
            if r["class"] in VEHICLES and float(r["visibility"]) >= 0.5:
                box = [float(r[k]) for k in ("bb_left", "bb_top", "bb_width", "bb_height")]
                truth[int(r["frame"])].append((box, float(r["speed_mps"]) < 0.1))
    for path in files:
        dets = defaultdict(list)
        with open(path) as f:
            for r in csv.DictReader(f):
                x, y, w, h = (float(r[k]) for k in "xywh")
                dets[int(r["frame"])].append((x - w / 2, y - h / 2, w, h))
        best = defaultdict(list)
        for frame, rows in truth.items():
            for box, standing in rows:
                score = max((iou(box, d) for d in dets[frame]), default=0.0)
                best["standing" if standing else "moving"].append(score)
        parts = []
        for kind in ("moving", "standing"):
            v = np.array(best[kind])
            if len(v):
                parts.append(f"{kind} {len(v)}: IoU ≥ 0.5 {np.mean(v >= 0.5):.2f}, "
                             f"≥ 0.75 {np.mean(v >= 0.75):.2f}")
        print(f"{path}: " + "; ".join(parts))


if __name__ == "__main__":
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    main(sys.argv[1], sys.argv[2:])
