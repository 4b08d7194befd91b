#!/usr/bin/env python3
"""Tracking from video (docs/EXPERIMENTS.md, "Tracking from video", issue 13): every
roadtrack method with each detector that needs no download, beside the MOG2 + norfair
peer (scripts/mog2_norfair.py), on the same simulated frames. Class-agnostic HOTA, DetA,
AssA, IDF1, MOTA by `roadtrack evaluate` (TrackEval's definitions). Prints per-seed rows,
then means over the seeds, then the best roadtrack (method, detector) per scene against
the peer.

    python scripts/video_tracking_table.py --roadtrack $CARGO_TARGET_DIR/release/roadtrack \\
        [--frames 300] [--seeds 1,2,3] [--scenes road,intersection,crossing] \\
        [--views aerial,oblique] [--detectors background,cnn] [--methods relaxation,mrf,pf,phd] \\
        [--cnn-args '--model F.onnx --pyramid 1' [--cnn-args …]] [--background-args …] \\
        [--work /tmp/vidtrack]

Run from the repository root (configs/ and models/detector.onnx are read from there).
Not part of the test suite; needs `pip install opencv-python-headless numpy norfair`.
"""
import argparse
import json
import os
import subprocess
import sys
from collections import defaultdict

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import mog2_norfair  # noqa: E402

# The settings each method uses in scripts/tracking_table.sh's best rows.
METHODS = [
    ("relaxation", ["--config", "configs/relaxation-video.toml"]),
    ("mrf", []),
    ("pf", ["--config", "configs/filters-pedestrians.toml"]),
    ("phd", []),
]
KEYS = ("HOTA", "DetA", "AssA", "IDF1", "MOTA")


def run(cmd):
    subprocess.run(cmd, check=True)


def evaluate(rt, seq, tracks):
    out = subprocess.run(
        [rt, "-q", "evaluate", "--truth", seq, "--tracks", tracks, "--classes", "agnostic", "--json"],
        check=True,
        capture_output=True,
        text=True,
    ).stdout
    m = json.loads(out)
    return {k: float(m[k]) for k in KEYS}


def print_means(title, labels, columns, rows):
    """A means table in markdown: `title`, a blank line, the header (text columns `labels`,
    number columns `columns`), then each row of `rows`, a (label cells, numbers) pair."""
    print(title)
    print()
    print("| " + " | ".join([*labels, *columns]) + " |")
    print("|" + " --- |" * len(labels) + " ---: |" * len(columns))
    for cells, values in rows:
        print("| " + " | ".join([*cells, *(f"{v:.3f}" for v in values)]) + " |", flush=True)


def sequence(rt, work, scene, view, seed, frames):
    """The simulated sequence folder `work/scene-view-seed`, simulated first if missing."""
    seq = f"{work}/{scene}-{view}-{seed}"
    if not os.path.exists(f"{seq}/seqinfo.ini"):
        run([rt, "-q", "simulate", "--scene", scene, "--view", view,
             "--frames", str(frames), "--seed", str(seed), "-o", seq])
    return seq


def learned_detections(rt, seq, name):
    """`--detections SEQ/NAME`: the learned detector's boxes, found once per sequence."""
    boxes = f"{seq}/{name}"
    if not os.path.exists(boxes):
        run([rt, "-q", "detect", seq, "--detector", "cnn", "-o", boxes])
    return ["--detections", boxes]


def add_common_arguments(ap):
    """The binary, the sequences and the methods: what scripts/smooth_table.py takes too."""
    ap.add_argument("--roadtrack", default="roadtrack")
    ap.add_argument("--frames", type=int, default=300)
    ap.add_argument("--seeds", default="1,2,3")
    ap.add_argument("--scenes", default="road,intersection,crossing")
    ap.add_argument("--views", default="aerial,oblique")
    ap.add_argument("--methods", default=",".join(m for m, _ in METHODS))
    ap.add_argument("--work", default="/tmp/vidtrack")


def main():
    ap = argparse.ArgumentParser()
    add_common_arguments(ap)
    ap.add_argument("--detectors", default="background,cnn")
    ap.add_argument("--cnn-args", action="append",
                    help="extra flags for --detector cnn, e.g. '--model F.onnx --pyramid 1' "
                         "(`--cnn-args=--keep-nested` for one flag); given more than once, "
                         "each is a row of its own on the same frames")
    ap.add_argument("--background-args", action="append",
                    help="the same for --detector background, e.g. "
                         "'--detector-config configs/detect-pedestrians.toml'")
    a = ap.parse_args()
    methods = [(m, e) for m, e in METHODS if m in a.methods.split(",")]
    variants = {"cnn": a.cnn_args or [""], "background": a.background_args or [""]}
    rt = a.roadtrack
    seeds = [int(s) for s in a.seeds.split(",")]
    os.makedirs(a.work, exist_ok=True)
    results = defaultdict(list)  # (scene/view, tracker) -> [metrics per seed]
    print("| scene | seed | tracker | " + " | ".join(KEYS) + " |")
    print("| --- | ---: | --- |" + " ---: |" * len(KEYS))
    for scene in a.scenes.split(","):
        for view in a.views.split(","):
            sv = f"{scene}/{view}"
            for seed in seeds:
                seq = sequence(rt, a.work, scene, view, seed, a.frames)
                t = f"{a.work}/t.txt"
                rows = []
                mog2_norfair.main(seq, t)
                rows.append(("MOG2 + norfair (peer)", evaluate(rt, seq, t)))
                for det in a.detectors.split(","):
                    for variant in variants.get(det, [""]):
                        for method, extra in methods:
                            det_extra = variant.replace("{seq}", seq).split()
                            run([rt, "-q", "track", seq, "--method", method, "--detector", det,
                                 *det_extra, *extra, "--seed", "0", "-o", t])
                            name = f"{method} + {det}"
                            if len(variants.get(det, [])) > 1:
                                name += f" [{variant or 'defaults'}]"
                            rows.append((name, evaluate(rt, seq, t)))
                for name, m in rows:
                    results[(sv, name)].append(m)
                    cells = " | ".join(f"{m[k]:.3f}" for k in KEYS)
                    print(f"| {sv} | {seed} | {name} | {cells} |", flush=True)
    print()
    means = {key: {k: sum(m[k] for m in ms) / len(ms) for k in KEYS}
             for key, ms in results.items()}
    print_means(f"Means over seeds {a.seeds}:", ["scene", "tracker"], KEYS,
                [(key, [m[k] for k in KEYS]) for key, m in means.items()])
    print()
    print("| scene | MOG2 + norfair HOTA | best roadtrack | HOTA | ratio |")
    print("| --- | ---: | --- | ---: | ---: |")
    for sv in dict.fromkeys(sv for sv, _ in results):
        peer = means[(sv, "MOG2 + norfair (peer)")]["HOTA"]
        ours = [(m["HOTA"], n) for (s, n), m in means.items() if s == sv and "peer" not in n]
        best, name = max(ours)
        ratio = f"{best / peer:.2f}" if peer > 0 else "–"
        print(f"| {sv} | {peer:.3f} | {name} | {best:.3f} | {ratio} |")


if __name__ == "__main__":
    main()
