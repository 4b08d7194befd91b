#!/usr/bin/env python3
"""Tracking from the learned detector's boxes found once per sequence (docs/EXPERIMENTS.md
"Zoom as a level"): for each `--variant NAME='detect flags'`, `roadtrack detect SEQ
--detector cnn FLAGS -o SEQ/cnn_NAME.csv` (skipped when the file exists), then every method
on that file (`track --detector file --detections`, each with its shipped config for
video), scored class-agnostic by `roadtrack evaluate`, beside the
MOG2 + norfair peer (scripts/mog2_norfair.py, SEQ/peer.txt) on the same frames. Prints
HOTA / DetA / AssA / IDF1 per seed and the means over the seeds.

    python scripts/detections_table.py --roadtrack $CARGO_TARGET_DIR/release/roadtrack \\
        --variant default= --variant level16='--zoom-small 16' \\
        [--frames 300] [--seeds 1,2,3] [--scenes road,intersection,crossing] \\
        [--views oblique] [--methods relaxation,mrf,pf,phd] [--work /tmp/vidtrack]

`{seq}` in a variant's flags is the sequence folder (`--calibration {seq}/calibration.toml`).
Run from the repository root. Not part of the test suite; the peer needs
`pip install opencv-python-headless numpy norfair`.
"""
import argparse
import os
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from video_tracking_table import add_common_arguments, evaluate, run, sequence  # noqa: E402

# Each method's shipped settings for video (docs/EXPERIMENTS.md "Box gain", "Dots").
METHODS = [
    ("relaxation", ["--config", "configs/relaxation-video.toml"]),
    ("mrf", []),
    ("pf", ["--config", "configs/filters-pedestrians.toml"]),
    ("phd", ["--config", "configs/filters-pedestrians.toml"]),
]
SHOWN = ("HOTA", "DetA", "AssA", "IDF1")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_common_arguments(ap)
    ap.set_defaults(views="oblique")
    ap.add_argument("--variant", action="append", required=True,
                    help="NAME='detect flags' (flags may be empty)")
    a = ap.parse_args()
    rt = a.roadtrack
    seeds = [int(s) for s in a.seeds.split(",")]
    variants = [v.split("=", 1) for v in a.variant]
    methods = [(m, extra) for m, extra in METHODS if m in a.methods.split(",")]
    os.makedirs(a.work, exist_ok=True)
    for scene in a.scenes.split(","):
        for view in a.views.split(","):
            rows = {}  # tracker -> [metrics per seed]
            for seed in seeds:
                seq = sequence(rt, a.work, scene, view, seed, a.frames)
                peer = f"{seq}/peer.txt"
                if not os.path.exists(peer):
                    import mog2_norfair
                    mog2_norfair.main(seq, peer)
                rows.setdefault("MOG2 + norfair (peer)", []).append(evaluate(rt, seq, peer))
                for name, flags in variants:
                    dets = f"{seq}/cnn_{name}.csv"
                    if not os.path.exists(dets):
                        # roadtrack writes it atomically: a cut run leaves no file.
                        run([rt, "-q", "detect", seq, "--detector", "cnn",
                             *flags.replace("{seq}", seq).split(), "-o", dets])
                    for method, extra in methods:
                        out = f"{seq}/t_{method}_{name}.txt"
                        run([rt, "-q", "track", seq, "--method", method, *extra,
                             "--detector", "file", "--detections", dets, "-o", out])
                        rows.setdefault(f"{method}, {name}", []).append(evaluate(rt, seq, out))
            print(f"\n{scene}/{view}, seeds {a.seeds}: HOTA / DetA / AssA / IDF1 per seed; mean")
            for tracker, ms in rows.items():
                per = "  ".join("/".join(f"{m[k]:.3f}" for k in SHOWN) for m in ms)
                mean = " / ".join(f"{sum(m[k] for m in ms) / len(ms):.3f}" for k in SHOWN)
                print(f"| {tracker} | {per} | **{mean}** |")


if __name__ == "__main__":
    main()
