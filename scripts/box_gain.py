#!/usr/bin/env python3
"""Measures the learned detector's box gain (docs/DETECTION.md "Box gain"): how much larger
the truth's boxes are than the network's, per detected class, on renders the detector was
neither trained nor scored on.

It simulates short sequences with the training's random cameras and traffic (the ranges of
roadtrack-learn's `random_sim_config`: scene, view, camera height, yaw, tilt and focal
length, aerial scale and rotation, density, walkers, noise, shadows, sun; seeds from
--seed-base, which neither the training's simulator seeds, 1000 and up, nor the evaluation's,
0–3, use), runs `roadtrack detect --detector cnn --no-box-gain` on them, matches each
truth box at least 90 % visible to a detection greedily by IoU ≥ 0.3, and fits per
detected class and side the line ln(true / detected) = a + b ln(s / 32), s = √(w h) of the
detected box clamped to 8–64 px (least absolute deviations, so a few wrong matches do not
pull it), as the detector applies it (`centernet::box_factor`). It prints, per class and by
view, the matches, the median ratios and the fitted terms; per class and detected height,
the median ratios; and last the `roadtrack train
--detector --box-gain` command that writes the terms of the classes in --classes into a
model (0, no change, for the others).

    python3 scripts/box_gain.py --roadtrack $CARGO_TARGET_DIR/release/roadtrack \\
        [--model models/detector.onnx] [--sequences 40] [--frames 20] [--seed-base 500] \\
        [--work /tmp/boxgain] [--classes pedestrian]

Run from the repository root. Not part of the test suite; needs only Python 3.11.
"""
import argparse
import math
import os
import random
import statistics
import subprocess
import sys
import tomllib

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from detection_compare import greedy_match, read_gt, read_ours  # noqa: E402

# The network's heat-map channels as `detect` names their class, in --box-gain order.
CHANNELS = ["car", "truck", "motorcycle", "pedestrian"]
# The camera yaw and tilt each scene's training renders vary around (random_sim_config).
YAW_TILT = {"road": (18.0, 13.0), "intersection": (38.0, 20.0), "crossing": (62.0, 26.0)}


def random_config(rng, defaults, frames, width):
    """A partial simulator TOML drawn as roadtrack-learn's `random_sim_config` draws one
    (colours and the image corruption aside)."""
    scene = ["road", "intersection", "crossing"][rng.randrange(3)]
    view = "aerial" if rng.random() < 0.5 else "oblique"
    yaw, tilt = YAW_TILT[scene]
    density = rng.uniform(0.5, 2.5)
    walkers = rng.uniform(0.5, 3.0)
    rotation = rng.randrange(4) * 90.0 if rng.random() < 0.5 else rng.uniform(0.0, 360.0)
    d = defaults
    return f"""scene = "{scene}"
view = "{view}"
frames = {frames}
fps = {rng.uniform(0.5, 2.0):.4f}
warmup_s = {rng.uniform(20.0, 150.0):.2f}
[aerial]
metres_per_pixel = {rng.uniform(0.2, 0.45):.4f}
rotation_deg = {rotation:.2f}
[oblique]
height_m = {rng.uniform(5.0, 14.0):.3f}
yaw_deg = {yaw + rng.uniform(-15.0, 15.0):.3f}
tilt_deg = {tilt + rng.uniform(-5.0, 12.0):.3f}
focal_px = {width * rng.uniform(0.55, 1.3):.2f}
[road]
inflow_veh_per_h = {d['road']['inflow_veh_per_h'] * density:.2f}
[intersection]
inflow_veh_per_h_per_approach = {d['intersection']['inflow_veh_per_h_per_approach'] * density:.2f}
pedestrian_groups_per_min_per_entry = {d['intersection']['pedestrian_groups_per_min_per_entry'] * walkers:.3f}
[crossing]
inflow_veh_per_h_per_direction = {d['crossing']['inflow_veh_per_h_per_direction'] * density:.2f}
pedestrian_groups_per_min_per_entry = {d['crossing']['pedestrian_groups_per_min_per_entry'] * walkers:.3f}
[render]
noise_sd = {rng.uniform(0.0, 8.0):.3f}
shadows = {"true" if rng.random() < 0.8 else "false"}
min_one_pixel = false
sun_azimuth_deg = {rng.uniform(0.0, 360.0):.2f}
sun_elevation_deg = {rng.uniform(25.0, 80.0):.2f}
""", f"{scene}/{view}"


def ratios(seq, dets_path, min_visibility):
    """(detected class, ln(s / 32), ln(w_true / w), ln(h_true / h), detected height) of
    each matched truth box, s = √(w h) of the detection clamped to 8–64 px."""
    gt = read_gt(seq)
    dets = read_ours(dets_path, with_class=True)
    out = []
    for frame, g in gt.items():
        g = [t for t in g if t[3] >= min_visibility]
        d = dets.get(frame, [])
        for i, j, _ in greedy_match([t[1] for t in g], [x[0] for x in d], 0.3):
            (_, _, gw, gh), ((_, _, dw, dh), cls) = g[i][1], d[j]
            size = min(max(math.sqrt(dw * dh), 8.0), 64.0)
            out.append((cls, math.log(size / 32.0), math.log(gw / dw), math.log(gh / dh), dh))
    return out


def lad_line(xs, ys, iterations=100):
    """(a, b) of the line y = a + b x with the least sum of absolute deviations
    (iteratively reweighted least squares)."""
    w = [1.0] * len(xs)
    a = b = 0.0
    for _ in range(iterations):
        sw = sum(w)
        sx = sum(wi * x for wi, x in zip(w, xs))
        sy = sum(wi * y for wi, y in zip(w, ys))
        sxx = sum(wi * x * x for wi, x in zip(w, xs))
        sxy = sum(wi * x * y for wi, x, y in zip(w, xs, ys))
        det = sw * sxx - sx * sx
        if det <= 0:
            return statistics.median(ys), 0.0
        b = (sw * sxy - sx * sy) / det
        a = (sy - b * sx) / sw
        w = [1.0 / max(abs(y - a - b * x), 1e-3) for x, y in zip(xs, ys)]
    return a, b


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--roadtrack", default="roadtrack")
    ap.add_argument("--model", default="models/detector.onnx")
    ap.add_argument("--sequences", type=int, default=40)
    ap.add_argument("--frames", type=int, default=20)
    ap.add_argument("--seed-base", type=int, default=500)
    ap.add_argument("--work", default="/tmp/boxgain")
    ap.add_argument("--min-visibility", type=float, default=0.9)
    ap.add_argument("--classes", default="pedestrian",
                    help="classes whose factors go into the command; the others get 1")
    a = ap.parse_args()
    os.makedirs(a.work, exist_ok=True)
    probe = f"{a.work}/defaults"
    if not os.path.isdir(probe):
        subprocess.run([a.roadtrack, "-q", "simulate", "--frames", "1", "-o", probe], check=True)
    with open(f"{probe}/simulation.toml", "rb") as f:
        defaults = tomllib.load(f)
    rows = []
    for k in range(a.sequences):
        seed = a.seed_base + k
        seq = f"{a.work}/s{seed}"
        text, kind = random_config(random.Random(seed), defaults, a.frames, defaults["width"])
        if not os.path.isdir(seq):
            cfg = f"{a.work}/c{seed}.toml"
            with open(cfg, "w") as f:
                f.write(text)
            subprocess.run([a.roadtrack, "-q", "simulate", "--config", cfg, "--seed", str(seed),
                            "-o", seq], check=True)
        dets = f"{seq}/cnn_raw.csv"
        subprocess.run([a.roadtrack, "-q", "detect", seq, "--detector", "cnn", "--model", a.model,
                        "--no-box-gain", "-o", dets], check=True)
        got = ratios(seq, dets, a.min_visibility)
        rows += [(kind.split("/")[1],) + r for r in got]
        print(f"seed {seed} {kind}: {len(got)} matches", file=sys.stderr, flush=True)
    print("| detected class | view | matches | median ln(w_true / w) | median ln(h_true / h) "
          "| a_w | b_w | a_h | b_h |")
    print("| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
    terms = []
    wanted = set(a.classes.split(","))
    for cls in CHANNELS:
        fitted = [0.0] * 4
        for view in ("all", "aerial", "oblique"):
            r = [x for x in rows if x[1] == cls and view in ("all", x[0])]
            if len(r) < 30:
                print(f"| {cls} | {view} | {len(r)} | – | – | – | – | – | – |")
                continue
            xs = [x[2] for x in r]
            aw, bw = lad_line(xs, [x[3] for x in r])
            ah, bh = lad_line(xs, [x[4] for x in r])
            print(f"| {cls} | {view} | {len(r)} | {statistics.median(x[3] for x in r):+.3f} "
                  f"| {statistics.median(x[4] for x in r):+.3f} | {aw:+.3f} | {bw:+.3f} "
                  f"| {ah:+.3f} | {bh:+.3f} |")
            if view == "all" and cls in wanted:
                fitted = [round(v, 3) for v in (aw, bw, ah, bh)]
        terms += fitted
    print()
    print("| detected class | detected height (px) | matches | median ln(w_true / w) "
          "| median ln(h_true / h) |")
    print("| --- | --- | ---: | ---: | ---: |")
    for cls in CHANNELS:
        for lo, hi in ((0, 15), (15, 25), (25, 40), (40, 70), (70, math.inf)):
            r = [x for x in rows if x[1] == cls and lo <= x[5] < hi]
            if len(r) >= 30:
                print(f"| {cls} | {lo}–{hi} | {len(r)} | {statistics.median(x[3] for x in r):+.3f} "
                      f"| {statistics.median(x[4] for x in r):+.3f} |")
    print()
    print("roadtrack train --detector --init MODEL.onnx --box-gain="
          + ",".join(f"{t:g}" for t in terms) + " -o OUT.onnx")


if __name__ == "__main__":
    main()
