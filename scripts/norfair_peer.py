#!/usr/bin/env python3
"""Peer tracker for docs/TRACKING.md: norfair (PyPI, 2.x) with IoU distance on a
sequence's public detections (det/det.txt), written as MOTChallenge tracks.

    python scripts/norfair_peer.py SEQ_DIR OUT.txt

Not part of the test suite; needs `pip install norfair`. Settings are norfair's IoU
example's: distance_threshold 0.7 (1 - IoU), hit_counter_max 15, initialization_delay
default (hit_counter_max / 2)."""
import sys
from collections import defaultdict

import numpy as np
from norfair import Detection, Tracker


def main(seq, out):
    dets = defaultdict(list)
    with open(f"{seq}/det/det.txt") as f:
        for line in f:
            c = line.strip().split(",")
            if len(c) < 6:
                continue
            frame, left, top, w, h = int(c[0]), *map(float, c[2:6])
            dets[frame].append(np.array([[left, top], [left + w, top + h]]))
    n_frames = max(dets) if dets else 0
    with open(f"{seq}/seqinfo.ini") as f:
        for line in f:
            if line.startswith("seqLength="):
                n_frames = int(line.split("=")[1])
    tracker = Tracker(distance_function="iou", distance_threshold=0.7)
    rows = []
    for frame in range(1, n_frames + 1):
        tracked = tracker.update([Detection(points=b) for b in dets.get(frame, [])])
        for t in tracked:
            (x0, y0), (x1, y1) = t.estimate
            # The Kalman estimate can swap corners for a moment: keep the box valid.
            x0, x1 = min(x0, x1), max(x0, x1)
            y0, y1 = min(y0, y1), max(y0, y1)
            rows.append(f"{frame},{t.id},{x0:.2f},{y0:.2f},{x1 - x0:.2f},{y1 - y0:.2f},1,-1,-1,-1")
    with open(out, "w") as f:
        f.write("\n".join(rows) + ("\n" if rows else ""))


if __name__ == "__main__":
    main(*sys.argv[1:3])
