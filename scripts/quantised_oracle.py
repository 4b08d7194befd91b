#!/usr/bin/env python3
"""An upper bound for walkers of 1-2 px (docs/EXPERIMENTS.md "The MRF's gate for dots"):
the truth's own tracks (ids and box sizes kept), each pedestrian's box centre moved to the
centroid of the pixel centres its box covers (what any detector working from the rendered
pixels can know of a 1-px walker; boxes that cover no pixel centre dropped); with
--fit N, each box then replaced by a straight-line fit, in time, of its track's boxes over
N frames on each side (as `track --smooth-boxes N`). Written as MOTChallenge tracks:

    python3 scripts/quantised_oracle.py SEQ OUT.txt [--fit 5]
    roadtrack evaluate --truth SEQ --tracks OUT.txt --classes agnostic

Not part of the test suite; needs only Python 3.
"""
import argparse
import math
from collections import defaultdict


def centres(lo, size):
    """Pixel centres (k + 0.5) within [lo, lo + size]."""
    return [k + 0.5 for k in range(math.ceil(lo - 0.5), math.floor(lo + size - 0.5) + 1)]


def fit(track, n):
    out = {}
    for f in track:
        pts = [(g, track[g]) for g in range(f - n, f + n + 1) if g in track]
        mt = sum(g for g, _ in pts) / len(pts)
        den = sum((g - mt) ** 2 for g, _ in pts)
        box = []
        for k in range(4):
            mv = sum(b[k] for _, b in pts) / len(pts)
            slope = sum((g - mt) * (b[k] - mv) for g, b in pts) / den if den > 0 else 0.0
            box.append(mv + slope * (f - mt))
        out[f] = box
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("seq")
    ap.add_argument("out")
    ap.add_argument("--fit", type=int, default=0)
    a = ap.parse_args()
    tracks = defaultdict(dict)
    with open(f"{a.seq}/gt/gt.txt") as f:
        for line in f:
            c = line.strip().split(",")
            frame, oid = int(c[0]), int(c[1])
            x, y, w, h = map(float, c[2:6])
            if int(c[7]) == 1:
                xs, ys = centres(x, w), centres(y, h)
                if not xs or not ys:
                    continue
                x, y = sum(xs) / len(xs) - w / 2, sum(ys) / len(ys) - h / 2
            tracks[oid][frame] = [x, y, w, h]
    rows = []
    for oid, track in tracks.items():
        boxes = fit(track, a.fit) if a.fit > 0 else track
        for frame, (x, y, w, h) in boxes.items():
            rows.append((frame, oid, f"{frame},{oid},{x:.3f},{y:.3f},{w:.3f},{h:.3f},1,-1,-1,-1"))
    with open(a.out, "w") as f:
        f.write("".join(r + "\n" for _, _, r in sorted(rows)))


if __name__ == "__main__":
    main()
