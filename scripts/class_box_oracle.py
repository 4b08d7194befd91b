#!/usr/bin/env python3
"""What perfect boxes for one kind of object would be worth (docs/EXPERIMENTS.md "Lorries'
boxes"): rewrites a MOT tracks file with every track box that overlaps a truth box of the
given MOT17 class (IoU above --min-iou; the truth box it overlaps most) replaced by that
truth box, ids, frames and scores kept. Score the output with `roadtrack evaluate` beside
the input: the difference is what the boxes of that class cost.

    python3 scripts/class_box_oracle.py SEQ TRACKS.txt OUT.txt --class 6 \\
        [--min-iou 0.1] [--max-visibility 1.0]

--class: the truth's MOT17 class (1 pedestrian, 3 car, 5 motorcycle, 6 lorry or bus);
--max-visibility: only truth boxes less visible than this (e.g. 0.5: the occluded ones).
Not part of the test suite; needs only Python 3 (and scripts/detection_compare.py beside it).
"""
import argparse
import os
import sys
from collections import defaultdict

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from detection_compare import iou  # noqa: E402


def read_gt(path):
    gt = defaultdict(list)
    with open(path) as f:
        for line in f:
            c = line.strip().split(",")
            if len(c) < 9 or c[6] == "0":
                continue
            gt[int(c[0])].append((tuple(map(float, c[2:6])), int(c[7]), float(c[8])))
    return gt


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("seq")
    ap.add_argument("tracks")
    ap.add_argument("out")
    ap.add_argument("--class", dest="cls", type=int, required=True)
    ap.add_argument("--min-iou", type=float, default=0.1)
    ap.add_argument("--max-visibility", type=float, default=1.0)
    a = ap.parse_args()
    gt = read_gt(f"{a.seq}/gt/gt.txt")
    replaced = total = 0
    with open(a.tracks) as f, open(a.out, "w") as out:
        for line in f:
            c = line.strip().split(",")
            box = tuple(map(float, c[2:6]))
            total += 1
            best, best_iou = None, a.min_iou
            for g, cls, vis in gt.get(int(c[0]), []):
                if cls != a.cls or (a.max_visibility < 1.0 and vis >= a.max_visibility):
                    continue
                v = iou(g, box)
                if v > best_iou:
                    best, best_iou = g, v
            if best is not None:
                c[2:6] = [f"{v:.3f}" for v in best]
                replaced += 1
            out.write(",".join(c) + "\n")
    print(f"{a.out}: {replaced} of {total} boxes replaced")


if __name__ == "__main__":
    main()
