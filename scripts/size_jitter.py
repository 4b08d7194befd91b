#!/usr/bin/env python3
"""Copies a detections CSV with every box's width and height multiplied by 1 + N(0, SD),
drawn from --seed: how much a tracker's score moves under a change of the boxes far smaller
than any that matters (docs/EXPERIMENTS.md "Box gain", the spread under a 0.1 % jitter).

    python3 scripts/size_jitter.py IN.csv OUT.csv [--sd 0.001] [--seed 1]

Then `roadtrack track SEQ --detector file --detections OUT.csv …` as for IN.csv. Not part
of the test suite; needs only Python 3.
"""
import argparse
import csv
import random


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("input")
    ap.add_argument("output")
    ap.add_argument("--sd", type=float, default=0.001)
    ap.add_argument("--seed", type=int, default=1)
    a = ap.parse_args()
    rng = random.Random(a.seed)
    with open(a.input, newline="") as f:
        rows = list(csv.DictReader(f))
    if not rows:
        raise SystemExit(f"{a.input}: no detections")
    with open(a.output, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
        w.writeheader()
        for d in rows:
            d["w"] = f"{float(d['w']) * (1 + rng.gauss(0, a.sd)):.4f}"
            d["h"] = f"{float(d['h']) * (1 + rng.gauss(0, a.sd)):.4f}"
            w.writerow(d)


if __name__ == "__main__":
    main()
