#!/usr/bin/env python3
"""Issue 13's "the background detector beats MOG2 on every scene", seed by seed: the
background detector's rows (default, default with the sequence's calibration, the
intersection and pedestrians configs) beside OpenCV MOG2 + contours on the simulator's six
scenes, recall of all objects (visibility >= 0.5) / precision at IoU 0.5, as
scripts/detection_compare.py scores them. A cell is marked x where MOG2 is not beaten on
both. With several binaries (--roadtrack NAME=PATH, repeated) each cell shows them in
order, e.g. before -> after a change, on the same frames in one run.

    python3 scripts/background_vs_mog2.py --roadtrack R --seeds 0,1,2 --work /tmp/bgmog2

Needs numpy and opencv-python-headless (for MOG2), as detection_compare.py does.
"""
import argparse
import os
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from detection_compare import (INTERSECTION_CONFIG, PEDESTRIANS_CONFIG,  # noqa: E402
                               mog2, read_gt, read_ours, read_stopped, score, sequence)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--roadtrack", action="append", default=[],
                    help="PATH or NAME=PATH of a roadtrack binary; repeat to compare")
    ap.add_argument("--seeds", default="0,1,2")
    ap.add_argument("--frames", type=int, default=300)
    ap.add_argument("--work", default="/tmp/bgmog2")
    a = ap.parse_args()
    binaries = [b.split("=", 1) if "=" in b else (b, b) for b in a.roadtrack or ["roadtrack"]]
    rows = [("default", lambda seq: []),
            ("default + calibration", lambda seq: ["--calibration", f"{seq}/calibration.toml"]),
            ("intersection config", lambda seq: ["--config", INTERSECTION_CONFIG,
                                                 "--calibration", f"{seq}/calibration.toml"]),
            ("pedestrians config", lambda seq: ["--config", PEDESTRIANS_CONFIG,
                                                "--calibration", f"{seq}/calibration.toml"])]
    names = " → ".join(n for n, _ in binaries)
    print(f"R all / P; binaries: {names}\n")
    print("| seed | scene | MOG2 | " + " | ".join(r for r, _ in rows) + " |")
    print("| --- | --- | --- | " + " | ".join("---" for _ in rows) + " |")
    lost = {r: 0 for r, _ in rows}
    for seed in a.seeds.split(","):
        for scene in ("road", "intersection", "crossing"):
            for view in ("aerial", "oblique"):
                seq = sequence(argparse.Namespace(roadtrack=binaries[0][1], work=a.work,
                                                  seed=int(seed), frames=a.frames), scene, view)
                gt, stopped = read_gt(seq), read_stopped(seq)
                m_rec, m_prec, _ = score(gt, mog2(seq, a.frames), stopped, a.frames)
                cells = [f"{m_rec['all']:.2f} / {m_prec:.2f}"]
                for row, flags in rows:
                    parts = []
                    for k, (_, binary) in enumerate(binaries):
                        out = f"{seq}/bg_{k}_{row.replace(' ', '_').replace('+', 'p')}.csv"
                        subprocess.run([binary, "-q", "detect", seq, "-o", out, *flags(seq)],
                                       check=True)
                        rec, prec, _ = score(gt, read_ours(out), stopped, a.frames)
                        beats = rec["all"] > m_rec["all"] and prec > m_prec
                        if not beats and k == len(binaries) - 1:
                            lost[row] += 1
                        parts.append(f"{rec['all']:.2f} / {prec:.2f}{'' if beats else ' x'}")
                    cells.append(" → ".join(parts))
                print(f"| {seed} | {scene} {view} | " + " | ".join(cells) + " |", flush=True)
    print("\nScenes x seeds where the last binary does not beat MOG2 on both: "
          + ", ".join(f"{r} {n}" for r, n in lost.items()))


if __name__ == "__main__":
    main()
