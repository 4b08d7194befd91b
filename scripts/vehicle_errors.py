#!/usr/bin/env python3
"""Where a detector's vehicle errors lie (docs/EXPERIMENTS.md "Learned detector"): on a
simulated sequence, its vehicle boxes unmatched at IoU 0.5 (one-to-one, best IoU first, as
scripts/detection_compare.py matches) split by their best IoU with any vehicle of the
truth (loose 0.3-0.5, weak 0.05-0.3, none), and the missed vehicles (visibility >= 0.5) by
class and by the best IoU any vehicle box reaches on them. A loose box is an error twice:
a false box and a missed vehicle.

    roadtrack detect SEQ --detector cnn -o SEQ/cnn.csv
    python3 scripts/vehicle_errors.py SEQ SEQ/cnn.csv [SEQ2 DETS2 ...]
"""
import os
import sys
from collections import Counter

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from detection_compare import greedy_match, iou, read_gt, read_ours  # noqa: E402

VEHICLES = {3: "car", 5: "motorcycle", 6: "lorry/bus"}
VEHICLE_NAMES = {"car", "truck", "bus", "motorcycle"}


def band(v):
    return "loose" if v >= 0.3 else "weak" if v >= 0.05 else "none"


def main():
    args = sys.argv[1:]
    if not args or len(args) % 2:
        sys.exit(__doc__)
    for seq, path in zip(args[::2], args[1::2]):
        gt, dets = read_gt(seq), read_ours(path, True)
        frames = max([*gt, *dets, 0])
        false, missed = Counter(), Counter()
        n_det = n_tp = n_gt = 0
        for f in range(1, frames + 1):
            g = [t for t in gt.get(f, []) if t[2] in VEHICLES]
            d = [b for b, c in dets.get(f, []) if c in VEHICLE_NAMES]
            m = greedy_match([t[1] for t in g], d, 0.5)
            used_d, used_g = {j for _, j, _ in m}, {i for i, _, _ in m}
            n_det, n_tp = n_det + len(d), n_tp + len(m)
            for j, b in enumerate(d):
                if j not in used_d:
                    false[band(max((iou(t[1], b) for t in g), default=0.0))] += 1
            for i, t in enumerate(g):
                if t[3] < 0.5:
                    continue
                n_gt += 1
                if i not in used_g:
                    best = max((iou(t[1], b) for b in d), default=0.0)
                    missed[(VEHICLES[t[2]], band(best))] += 1
        print(f"{os.path.basename(seq.rstrip('/'))}: {n_det} vehicle boxes, "
              f"precision {n_tp / max(n_det, 1):.3f}")
        print("  false boxes by best IoU with a vehicle: "
              + ", ".join(f"{k} {v}" for k, v in sorted(false.items())))
        print(f"  missed vehicles ({sum(missed.values())} of {n_gt}) by class / best IoU: "
              + ", ".join(f"{c} {b} {v}" for (c, b), v in sorted(missed.items())))


if __name__ == "__main__":
    main()
