#!/usr/bin/env python3
"""Recall and precision of the pedestrians of a detections CSV against a sequence's
gt/gt.txt, matching centres within --radius px (one to one per frame, Hungarian).

For walkers of 1-2 px (aerial views), where IoU 0.5 asks for a centre within a third of a
pixel, the centre distance says whether they are found at all; docs/DETECTION.md "Dots".

    roadtrack detect SEQ --detector cnn --dots --calibration SEQ/calibration.toml -o D.csv
    python3 scripts/dot_recall.py SEQ D.csv

Truth: gt.txt rows of class 1 (pedestrian) with visibility >= --min-visibility. Also
prints how much the dots' centres lock to pixel centres (docs/EXPERIMENTS.md "What holds
the scenes under 0.6").
Detections: the CSV's rows of class "pedestrian". Needs numpy and scipy.
"""
import argparse
import csv

import numpy as np
from scipy.optimize import linear_sum_assignment


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("sequence")
    ap.add_argument("detections")
    ap.add_argument("--radius", type=float, default=1.5)
    ap.add_argument("--min-visibility", type=float, default=0.5)
    a = ap.parse_args()
    gt = np.loadtxt(f"{a.sequence}/gt/gt.txt", delimiter=",", ndmin=2)
    walkers = gt[(gt[:, 7] == 1) & (gt[:, 8] >= a.min_visibility)]
    with open(a.detections, newline="") as f:
        rows = [r for r in csv.DictReader(f) if r.get("class") == "pedestrian"]
    det = np.array([[float(r["frame"]), float(r["x"]), float(r["y"])] for r in rows]).reshape(-1, 3)
    found = 0
    dist = []
    phase, err = [], []  # per matched pair: truth centre's offset from its pixel's centre, error
    for t in np.unique(walkers[:, 0]):
        g = walkers[walkers[:, 0] == t]
        d = det[det[:, 0] == t]
        if len(d) == 0:
            continue
        centres = np.stack([g[:, 2] + g[:, 4] / 2, g[:, 3] + g[:, 5] / 2], 1)
        cost = np.hypot(centres[:, None, 0] - d[None, :, 1], centres[:, None, 1] - d[None, :, 2])
        # Pairs beyond the radius cost more than any within it, so the assignment makes as
        # many pairs within the radius as it can (a plain sum of distances could trade a
        # close pair for two distant ones).
        r, c = linear_sum_assignment(np.where(cost < a.radius, cost, 1e6))
        ok = cost[r, c] < a.radius
        found += int(ok.sum())
        dist.extend(cost[r, c][ok])
        t, e = centres[r[ok]], d[c[ok], 1:] - centres[r[ok]]
        phase.extend(t - 0.5 - np.round(t - 0.5))
        err.extend(e)
    recall = found / max(len(walkers), 1)
    precision = found / max(len(det), 1)
    median = float(np.median(dist)) if dist else float("nan")
    print(f"walkers {len(walkers)} dots {len(det)} recall {recall:.3f} precision {precision:.3f} "
          f"median centre error {median:.2f} px")
    if len(err) > 2:
        # Pixel locking: the slope of the error against the truth centre's offset from the
        # centre of its pixel, per axis; -1 = every dot at a pixel centre, 0 = none.
        ph, er = np.array(phase), np.array(err)
        slopes = [np.polyfit(ph[:, k], er[:, k], 1)[0] for k in (0, 1)]
        print(f"pixel locking: slope x {slopes[0]:.2f}, y {slopes[1]:.2f}")


if __name__ == "__main__":
    main()
