#!/usr/bin/env python3
"""Objects per frame against the truth: roadtrack's PHD counts beside two peers on the
same public detections (docs/EXPERIMENTS.md "The count smoothed over the next frame",
issue 14 target 2).

    python3 scripts/count_peers.py ROADTRACK SEQ_DIR... [--config configs/filters-pedestrians.toml]

(`--config configs/phd-road.toml` for road sequences: docs/EXPERIMENTS.md "The PHD on
roads".)

For each sequence folder (from `roadtrack simulate`): runs `ROADTRACK track SEQ --method
phd --detector file --config C --seed S --counts` (S = the sequence's seed, from
simulation.toml) and norfair's IoU tracker (scripts/norfair_peer.py's settings) on
det/det.txt, then prints the mean |count - truth| per frame, the truth being the objects
the simulated detector can see (truth.csv visibility >= 0.3, the image border not
counted, as the library's count experiment scores them). Counts: the detections in the
frame; norfair's tracks in the frame; the PHD's Σw and its mode; both smoothed over the
next frame; the PHD's tracks written before the life-cycle stages.

Not part of the test suite; needs `pip install norfair`.
"""
import argparse
import csv
import os
import subprocess
import sys
import tempfile
from collections import Counter

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import norfair_peer  # noqa: E402
from norfair_peer import seq_length  # noqa: E402

COLUMNS = [
    ("detections", "detections"),
    ("norfair tracks", None),
    ("PHD Σw", "expected"),
    ("PHD mode", "most_probable"),
    ("PHD Σw smoothed", "smoothed"),
    ("PHD mode smoothed", "smoothed_most_probable"),
    ("PHD tracks", "reported"),
]


def seed_of(seq):
    with open(os.path.join(seq, "simulation.toml")) as f:
        for line in f:
            if line.startswith("# seed = "):
                return int(line.split("=")[1])
    raise SystemExit(f"{seq}/simulation.toml: no `# seed = ` line")


def truth_counts(seq):
    n = Counter()
    with open(os.path.join(seq, "truth.csv")) as f:
        for r in csv.DictReader(f):
            if float(r["visibility"]) >= 0.3:
                n[int(r["frame"])] += 1
    return n


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("roadtrack")
    ap.add_argument("seqs", nargs="+")
    ap.add_argument("--config", default="configs/filters-pedestrians.toml")
    a = ap.parse_args()
    print("| sequence | true mean | " + " | ".join(c for c, _ in COLUMNS) + " |")
    print("| --- | ---: | " + " | ".join("---:" for _ in COLUMNS) + " |")
    for seq in a.seqs:
        truth = truth_counts(seq)
        n_frames = seq_length(seq)
        with tempfile.TemporaryDirectory() as tmp:
            counts_csv = os.path.join(tmp, "counts.csv")
            subprocess.run(
                [a.roadtrack, "-q", "track", seq, "--method", "phd", "--detector", "file",
                 "--config", a.config, "--seed", str(seed_of(seq)),
                 "-o", os.path.join(tmp, "phd.txt"), "--counts", counts_csv],
                check=True)
            with open(counts_csv) as f:
                ours = {int(r["frame"]): r for r in csv.DictReader(f)}
            norfair_txt = os.path.join(tmp, "norfair.txt")
            norfair_peer.main(seq, norfair_txt)
            peer = Counter()
            with open(norfair_txt) as f:
                for line in f:
                    peer[int(line.split(",")[0])] += 1
        frames = range(1, n_frames + 1)
        cells = []
        for _, key in COLUMNS:
            if key is None:
                err = [abs(peer[k] - truth[k]) for k in frames]
            else:
                err = [abs(float(ours[k][key]) - truth[k]) for k in frames]
            cells.append(f"{sum(err) / len(err):.3f}")
        mean = sum(truth[k] for k in frames) / len(frames)
        print(f"| {os.path.basename(os.path.normpath(seq))} | {mean:.2f} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
