#!/usr/bin/env python3
"""Peer tracker for docs/TRACKING.md: norfair (PyPI, 2.x) with IoU distance on a
sequence's public detections (det/det.txt), written as MOTChallenge tracks.

    python scripts/norfair_peer.py SEQ_DIR OUT.txt [DETECTIONS.csv]

DETECTIONS.csv: a roadtrack detections CSV (`roadtrack detect -o`) instead of det.txt.

Not part of the test suite; needs `pip install norfair`. Settings are norfair's IoU
example's: distance_threshold 0.7 (1 - IoU), hit_counter_max 15, initialization_delay
default (hit_counter_max / 2)."""
import sys
from collections import defaultdict

import numpy as np
from norfair import Detection, Tracker


def seq_length(seq, default=0):
    """`seqLength` of SEQ/seqinfo.ini (default when absent)."""
    with open(f"{seq}/seqinfo.ini") as f:
        for line in f:
            if line.startswith("seqLength="):
                return int(line.split("=")[1])
    return default


def track(boxes, n_frames, out):
    """norfair's IoU tracker over `boxes` (frame → list of (left, top, w, h)), frames
    1..n_frames, written to OUT as MOTChallenge tracks."""
    tracker = Tracker(distance_function="iou", distance_threshold=0.7)
    rows = []
    for frame in range(1, n_frames + 1):
        dets = [
            Detection(points=np.array([[x, y], [x + w, y + h]]))
            for x, y, w, h in boxes.get(frame, [])
        ]
        for t in tracker.update(dets):
            (x0, y0), (x1, y1) = t.estimate
            # The Kalman estimate can swap corners for a moment: keep the box valid.
            x0, x1 = min(x0, x1), max(x0, x1)
            y0, y1 = min(y0, y1), max(y0, y1)
            rows.append(f"{frame},{t.id},{x0:.2f},{y0:.2f},{x1 - x0:.2f},{y1 - y0:.2f},1,-1,-1,-1")
    with open(out, "w") as f:
        f.write("\n".join(rows) + ("\n" if rows else ""))


def main(seq, out, detections=None):
    if detections:
        from detection_compare import read_ours

        boxes = read_ours(detections)
        track(boxes, seq_length(seq, max(boxes) if boxes else 0), out)
        return
    boxes = defaultdict(list)
    with open(f"{seq}/det/det.txt") as f:
        for line in f:
            c = line.strip().split(",")
            if len(c) < 6:
                continue
            boxes[int(c[0])].append(tuple(map(float, c[2:6])))
    track(boxes, seq_length(seq, max(boxes) if boxes else 0), out)


if __name__ == "__main__":
    main(*sys.argv[1:4])
