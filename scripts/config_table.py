#!/usr/bin/env python3
"""One method under several config files on the simulator's six scenes (docs/EXPERIMENTS.md
"The MRF at junctions"): `track --detector file` on the sequence's own detections
(det/det.txt) and on the learned detector's boxes (`detect --detector cnn`, found once per
sequence into SEQ/cnn_g.csv, as scripts/detections_table.py's variant `g`), scored
class-agnostic by `roadtrack evaluate`, beside norfair's IoU tracker (scripts/norfair_peer.py)
on the same detections. Prints HOTA means over the seeds, one row per tracker or config and
detections, one column per scene.

    python3 scripts/config_table.py --roadtrack $CARGO_TARGET_DIR/release/roadtrack \\
        --method mrf --config defaults= --config junction=configs/mrf-intersection.toml \\
        [--frames 300] [--seeds 1,2,3] [--work /tmp/vidtrack]

`NAME=` (no path) runs the method's defaults; the peer's rows come first. Run from the
repository root. Not part of the test suite; needs `pip install opencv-python-headless
numpy norfair` (scripts/video_tracking_table.py and the peer import them).
"""
import argparse
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from detection_compare import read_ours  # noqa: E402
from video_tracking_table import evaluate, learned_detections, run, sequence  # noqa: E402
import norfair_peer  # noqa: E402

SCENES = [(s, v) for s in ("road", "intersection", "crossing") for v in ("aerial", "oblique")]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--roadtrack", default="roadtrack")
    ap.add_argument("--method", required=True)
    ap.add_argument("--config", action="append", required=True, help="NAME=path or NAME=")
    ap.add_argument("--frames", type=int, default=300)
    ap.add_argument("--seeds", default="1,2,3")
    ap.add_argument("--work", default="/tmp/vidtrack")
    a = ap.parse_args()
    rt = a.roadtrack
    seeds = [int(s) for s in a.seeds.split(",")]
    configs = [c.split("=", 1) for c in a.config]
    os.makedirs(a.work, exist_ok=True)
    print("| config | detections | " + " | ".join(f"{s} {v}" for s, v in SCENES) + " |")
    print("| --- | --- |" + " ---: |" * len(SCENES))
    for name, path in [("norfair (peer)", None)] + configs:
        for source in ("det.txt", "learned"):
            cells = []
            for scene, view in SCENES:
                hota = []
                for seed in seeds:
                    seq = sequence(rt, a.work, scene, view, seed, a.frames)
                    extra = learned_detections(rt, seq, "cnn_g.csv") if source == "learned" else []
                    if path is None:  # the peer on the same detections
                        out = f"{seq}/t_norfair_{source}.txt"
                        if source == "learned":
                            norfair_peer.track(read_ours(extra[1]), norfair_peer.seq_length(seq), out)
                        else:
                            norfair_peer.main(seq, out)
                        hota.append(evaluate(rt, seq, out)["HOTA"])
                        continue
                    out = f"{seq}/t_{a.method}_{name}_{source}.txt"
                    run([rt, "-q", "track", seq, "--method", a.method, "--detector", "file",
                         *extra, *(["--config", path] if path else []), "-o", out])
                    hota.append(evaluate(rt, seq, out)["HOTA"])
                cells.append(f"{sum(hota) / len(hota):.3f}")
            print(f"| {name} | {source} | " + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    main()
