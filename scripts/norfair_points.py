#!/usr/bin/env python3
"""Peer tracker for docs/EXPERIMENTS.md "The MRF's gate for dots": norfair (PyPI, 2.x) on
the centres of a detections CSV (`roadtrack detect -o F.csv`), matched by centre distance
(`mean_euclidean`, one point per detection) instead of IoU, which a 1-px box defeats. Each
track is written with the size of its last detection, as MOTChallenge tracks.

    python3 scripts/norfair_points.py SEQ_DIR DETS.csv OUT.txt [--threshold PX]
        [--hit-counter-max N] [--initialization-delay N]

Defaults: distance_threshold 1.5 px (3 px scored lower on the aerial crossing),
hit_counter_max 15, initialization_delay 3 (norfair requires it below hit_counter_max). Not part of the test suite; needs
`pip install norfair`.
"""
import argparse
import csv
from collections import defaultdict

import numpy as np
from norfair import Detection, Tracker

from norfair_peer import seq_length


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("seq")
    ap.add_argument("dets")
    ap.add_argument("out")
    ap.add_argument("--threshold", type=float, default=1.5)
    ap.add_argument("--hit-counter-max", type=int, default=15)
    ap.add_argument("--initialization-delay", type=int, default=3)
    a = ap.parse_args()
    boxes = defaultdict(list)
    with open(a.dets) as f:
        for row in csv.DictReader(f):
            boxes[int(row["frame"])].append(tuple(float(row[k]) for k in "xywh"))
    tracker = Tracker(
        distance_function="mean_euclidean",
        distance_threshold=a.threshold,
        hit_counter_max=a.hit_counter_max,
        initialization_delay=a.initialization_delay,
    )
    rows = []
    for frame in range(1, seq_length(a.seq, max(boxes) if boxes else 0) + 1):
        dets = [
            Detection(points=np.array([[x, y]]), data=(w, h))
            for x, y, w, h in boxes.get(frame, [])
        ]
        for t in tracker.update(dets):
            if t.last_detection is None:
                continue
            ((x, y),) = t.estimate
            w, h = t.last_detection.data
            rows.append(f"{frame},{t.id},{x - w / 2:.3f},{y - h / 2:.3f},{w:.3f},{h:.3f},1,-1,-1,-1")
    with open(a.out, "w") as f:
        f.write("\n".join(rows) + ("\n" if rows else ""))


if __name__ == "__main__":
    main()
