#!/usr/bin/env python3
"""HOTA of one scene's pipeline from video over several tracker seeds (docs/EXPERIMENTS.md
"Vehicles the background model has absorbed"): the PHD resamples its particles, so the
same boxes tracked with another `--seed` score differently, by up to ±0.008 on the aerial
junction. A comparison of two sets of boxes is steadier over the mean of a few seeds.

    python scripts/seed_spread.py --roadtrack $CARGO_TARGET_DIR/release/roadtrack \\
        --scene intersection-aerial --seq SEQ [--tracker-seeds S,11,12,13] D.csv [R.csv …]

SEQ is a `roadtrack simulate` folder; each CSV a detections file for it (`roadtrack detect`
output), tracked with the scene's recipe of `scripts/refine_table.py` (its `RECIPES`, without
the refinement flags: give refined boxes as their own file). `S` in the seeds stands for the
sequence's seed (the last number of its folder name). Prints, per file, the class-agnostic
HOTA / DetA / AssA means and each seed's HOTA. Run from the repository root; not part of the
test suite.
"""
import argparse
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from refine_table import RECIPES  # noqa: E402
from video_tracking_table import evaluate, run  # noqa: E402


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--roadtrack", default="roadtrack")
    ap.add_argument("--scene", required=True, choices=sorted(RECIPES))
    ap.add_argument("--seq", required=True)
    ap.add_argument("--tracker-seeds", default="S,11,12,13")
    ap.add_argument("--work", default="/tmp/seed_spread")
    ap.add_argument("detections", nargs="+")
    a = ap.parse_args()
    _, _, method, extra, _ = RECIPES[a.scene]
    own = a.seq.rstrip("/").rsplit("-", 1)[-1]
    seeds = [own if s == "S" else s for s in a.tracker_seeds.split(",")]
    os.makedirs(a.work, exist_ok=True)
    tracks = f"{a.work}/tracks.txt"
    for boxes in a.detections:
        scores = []
        for seed in seeds:
            run([a.roadtrack, "-q", "track", a.seq, "--method", method, "--detector", "file",
                 "--detections", boxes, *(f.replace("{seq}", a.seq) for f in extra), "--seed",
                 seed, "-o", tracks])
            scores.append(evaluate(a.roadtrack, a.seq, tracks))
        mean = {k: sum(s[k] for s in scores) / len(scores) for k in ("HOTA", "DetA", "AssA")}
        each = " ".join(f"{s['HOTA']:.4f}" for s in scores)
        print(f"{boxes}: HOTA {mean['HOTA']:.4f} DetA {mean['DetA']:.4f} "
              f"AssA {mean['AssA']:.4f} (seeds {','.join(seeds)}: {each})", flush=True)


if __name__ == "__main__":
    main()
