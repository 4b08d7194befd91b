#!/usr/bin/env python3
"""Box smoothing on public detections (docs/EXPERIMENTS.md, "Box smoothing"): every
roadtrack method on each simulated sequence's own det/det.txt, with `--smooth-boxes 0`
(off) and with the default, on the same frames; class-agnostic HOTA, DetA, AssA, IDF1,
MOTA by `roadtrack evaluate`, means over the seeds.

    python3 scripts/smooth_table.py --roadtrack $CARGO_TARGET_DIR/release/roadtrack \\
        [--frames 300] [--seeds 1,2,3] [--scenes road,intersection,crossing] \\
        [--views aerial,oblique] [--methods relaxation,mrf,pf,phd] [--work /tmp/vidtrack]

Run from the repository root (configs/ is read from there). Not part of the test suite.
The learned detector's side of the comparison is scripts/video_tracking_table.py with
`--cnn-args="--smooth-boxes 0" --cnn-args=`.
"""
import argparse
import os
import sys
from collections import defaultdict

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from video_tracking_table import (  # noqa: E402
    KEYS, METHODS, add_common_arguments, evaluate, print_means, run)

VARIANTS = [("off (--smooth-boxes 0)", ["--smooth-boxes", "0"]), ("default", [])]


def main():
    ap = argparse.ArgumentParser()
    add_common_arguments(ap)
    a = ap.parse_args()
    rt = a.roadtrack
    methods = [(m, e) for m, e in METHODS if m in a.methods.split(",")]
    os.makedirs(a.work, exist_ok=True)
    results = defaultdict(list)
    for scene in a.scenes.split(","):
        for view in a.views.split(","):
            for seed in [int(s) for s in a.seeds.split(",")]:
                seq = f"{a.work}/{scene}-{view}-{seed}"
                if not os.path.exists(f"{seq}/seqinfo.ini"):
                    run([rt, "-q", "simulate", "--scene", scene, "--view", view,
                         "--frames", str(a.frames), "--seed", str(seed), "-o", seq])
                t = f"{a.work}/smooth_t.txt"
                for method, extra in methods:
                    for name, flags in VARIANTS:
                        run([rt, "-q", "track", seq, "--method", method, "--detector", "file",
                             *extra, *flags, "--seed", "0", "-o", t])
                        results[(f"{scene}/{view}", method, name)].append(evaluate(rt, seq, t))
    print_means(f"Means over seeds {a.seeds}, public detections:",
                ["scene", "method", "smoothing"], KEYS,
                [(key, [sum(m[k] for m in ms) / len(ms) for k in KEYS])
                 for key, ms in results.items()])


if __name__ == "__main__":
    main()
