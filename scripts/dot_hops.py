#!/usr/bin/env python3
"""How often a track of dots hops to another walker (docs/EXPERIMENTS.md "The MRF's gate
for dots"): for each track's boxes under 3 px (walkers seen from above), the walker of the
truth nearest each box centre within 1 px (sequence gt/gt.txt, pedestrians); a hop is a
step between consecutive frames of one track whose walker changes. Run the tracker without
the offline fit and gap filling, so that the written boxes are the detector's:

    roadtrack track SEQ --method mrf --config C --smooth-boxes 0 --coast-frames 0 \\
        --detector file --detections DETS.csv -o T.txt
    python3 scripts/dot_hops.py SEQ T.txt [T2.txt ...]

Not part of the test suite; needs only Python 3.
"""
import os
import sys
from collections import defaultdict

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from detection_compare import read_gt  # noqa: E402


def hops(gt, path):
    tracks = defaultdict(dict)
    with open(path) as f:
        for line in f:
            c = line.split(",")
            x, y, w, h = map(float, c[2:6])
            if max(w, h) < 3:
                tracks[int(c[1])][int(c[0])] = (x + w / 2, y + h / 2)
    steps = changes = 0
    for frames in tracks.values():
        prev = None
        for frame in sorted(frames):
            x, y = frames[frame]
            near = [
                (((x - b[0] - b[2] / 2) ** 2 + (y - b[1] - b[3] / 2) ** 2) ** 0.5, oid)
                for oid, b, cls, _ in gt.get(frame, [])
                if cls == 1
            ]
            d, walker = min(near, default=(99.0, None))
            walker = walker if d <= 1.0 else None
            if prev is not None and walker is not None and frame - 1 in frames:
                steps += 1
                changes += walker != prev
            if walker is not None:
                prev = walker
    return steps, changes


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    gt = read_gt(sys.argv[1])
    for path in sys.argv[2:]:
        steps, changes = hops(gt, path)
        share = 100.0 * changes / steps if steps else float("nan")
        print(f"{path}: {steps} steps of dot tracks, {changes} hops to another walker ({share:.1f} %)")


if __name__ == "__main__":
    main()
