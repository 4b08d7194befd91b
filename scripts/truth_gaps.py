#!/usr/bin/env python3
"""Frames missing from each object's truth inside its life, per class: the rows an object
lacks between its first and last frame in `truth.csv` (docs/SIMULATOR.md "Objects under a
pixel", docs/EXPERIMENTS.md "Walkers under a pixel").

    python3 scripts/truth_gaps.py SEQ_DIR...

Prints, per sequence and class: truth rows, missing rows, missing rows per frame. With
`[render] min_one_pixel = false` a walker seen from above that covers no pixel centre has no
row in that frame; with the default every class prints 0. Not part of the test suite.
"""
import csv
import os
import sys
from collections import defaultdict


def main(seqs):
    print("| sequence | class | rows | missing | missing per frame |")
    print("| --- | --- | ---: | ---: | ---: |")
    for seq in seqs:
        frames, cls = defaultdict(set), {}
        with open(os.path.join(seq, "truth.csv")) as f:
            for r in csv.DictReader(f):
                frames[int(r["id"])].add(int(r["frame"]))
                cls[int(r["id"])] = r["class"]
        if not frames:
            raise SystemExit(f"{seq}/truth.csv: no rows")
        n = max(max(s) for s in frames.values())
        rows, gaps = defaultdict(int), defaultdict(int)
        for i, s in frames.items():
            rows[cls[i]] += len(s)
            gaps[cls[i]] += max(s) - min(s) + 1 - len(s)
        name = os.path.basename(os.path.normpath(seq))
        for c in sorted(rows):
            print(f"| {name} | {c} | {rows[c]} | {gaps[c]} | {gaps[c] / n:.2f} |")


if __name__ == "__main__":
    if len(sys.argv) < 2:
        raise SystemExit(__doc__)
    main(sys.argv[1:])
