#!/usr/bin/env python3
"""Detection recall and precision at IoU 0.5 on the simulator's scenes (docs/EXPERIMENTS.md,
"Detection"): roadtrack's background detector as it was (median start-up, no shadow
suppression, hold, ghost suppression or splitting), as it is by default, with region splitting
(`--calibration … --split`), and with the settings for cameras that watch people
(`--config configs/detect-pedestrians.toml --calibration …`), with the settings for cameras that
watch vehicles and people (`--config configs/detect-intersection.toml --calibration …`), and
OpenCV's MOG2 + contours, on the same frames.

    python scripts/detection_compare.py --roadtrack target/release/roadtrack \\
        --frames 300 --seed 1 --work /tmp/detcmp [--scenes road,intersection,crossing] \\
        [--views aerial,oblique] [--cnn-model models/detector.onnx] \\
        [--config-row 'name=path/to.toml' …]

Each --config-row adds a background-detector row run with `--config path/to.toml` (on the
same frames as the others, e.g. the default with one setting changed); flags after the path
are passed too, `{seq}` standing for the sequence folder (`'name=p.toml --calibration
{seq}/calibration.toml'`).

With --cnn-model, the learned detector (`--detector cnn`) gets a row too, and a second
table gives its recall and precision for vehicles and pedestrians separately (precision
over the detections it labels vehicle or pedestrian; matching stays class-agnostic).
With --recipes it runs with each scene's own detect flags, those of the scene's pipeline
from video (docs/TRACKING.md; `scripts/refine_table.py` RECIPES: the mirror upside down from
above, the zoom on the oblique road and intersection, `--min-score 0.5` on the crossing).

Not part of the test suite; needs `pip install opencv-python-headless numpy`.

Matching: per frame, detections and ground-truth boxes (gt/gt.txt) are paired greedily by
decreasing IoU, pairs below 0.5 dropped. Recall per MOT17 class (column 8: 1 pedestrian,
3 car, 5 motorcycle, 6 lorry/bus) and for vehicles standing still (truth.csv speed below
0.5 m/s; "arrived": those among them seen moving earlier in the sequence, i.e. not
standing there from the first frame), over ground-truth objects at least half visible (column 9 ≥ 0.5: heavily
occluded objects cannot be found by any region detector); precision over all detections
(a detection matched to a less visible object counts as correct).
"""
import argparse
import csv
import math
import os
import subprocess
from collections import defaultdict

try:
    import cv2
    import numpy as np
except ImportError:  # --only-cnn needs neither
    cv2 = np = None

OLD_CONFIG = """[background]
startup = "median"
shadows = false
hold_still_s = 0.0
ghost_edge_ratio = 0.0

[regions]
position = "centroid"
age_gap_s = 0.0

[split]
enabled = false
"""

CLASSES = {1: "ped", 3: "car", 5: "moto", 6: "lorry/bus"}

# The background detector's settings for cameras that watch people (people side by side cut
# apart; with the calibration, regions much smaller than a person there dropped).
PEDESTRIANS_CONFIG = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "configs",
                                  "detect-pedestrians.toml")
# For cameras that watch vehicles and people (the person share with its lower floor).
INTERSECTION_CONFIG = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "configs",
                                   "detect-intersection.toml")


def read_gt(seq):
    gt = defaultdict(list)
    with open(f"{seq}/gt/gt.txt") as f:
        for line in f:
            c = line.strip().split(",")
            if len(c) < 9:
                continue
            frame, oid = int(c[0]), int(c[1])
            box = tuple(map(float, c[2:6]))
            gt[frame].append((oid, box, int(c[7]), float(c[8])))
    return gt


def read_stopped(seq):
    """(frame, id) of vehicles standing still, and of those among them seen moving before
    (they arrived in the sequence and stopped)."""
    stopped, arrived, moved = set(), set(), set()
    rows = []
    with open(f"{seq}/truth.csv") as f:
        for row in csv.DictReader(f):
            rows.append((int(row["frame"]), int(row["id"]), float(row["speed_mps"])))
    for frame, oid, speed in sorted(rows):
        if speed < 0.5:
            stopped.add((frame, oid))
            if oid in moved:
                arrived.add((frame, oid))
        else:
            moved.add(oid)
    return stopped, arrived


def read_ours(path, with_class=False):
    dets = defaultdict(list)
    with open(path) as f:
        for row in csv.DictReader(f):
            x, y, w, h = (float(row[k]) for k in "xywh")
            box = (x - w / 2, y - h / 2, w, h)
            dets[int(row["frame"])].append((box, row.get("class", "")) if with_class else box)
    return dets


def frame_size(seq):
    """(width, height) from seqinfo.ini."""
    size = {}
    with open(f"{seq}/seqinfo.ini") as f:
        for line in f:
            k, _, v = line.strip().partition("=")
            if k in ("imWidth", "imHeight"):
                size[k] = float(v)
    return size["imWidth"], size["imHeight"]


def score_groups(gt, dets, n_frames, size):
    """Recall (visibility ≥ 0.5) and precision for vehicles and pedestrians: greedy
    class-agnostic matching at IoU 0.5; a detection counts for the group of its class.
    "cut": vehicles whose box (clipped to the frame by the simulator) reaches within 1 px
    of the frame's edge. Also the mean IoU of the found vehicles' boxes ("loc") and the
    mean |ln(w_det / w_true)| + |ln(h_det / h_true)| / 2 over them ("size"): how tight the
    boxes HOTA's localisation scores are."""
    hit, tot, det_n, det_ok = (defaultdict(int) for _ in range(4))
    ious, size_err = [], []
    for frame in range(1, n_frames + 1):
        g = gt.get(frame, [])
        d = dets.get(frame, [])
        matches = greedy_match([t[1] for t in g], [x[0] for x in d], 0.5)
        used_g = {i for i, _, _ in matches}
        used_d = {j for _, j, _ in matches}
        for i, j, v in matches:
            if g[i][3] >= 0.5 and g[i][2] != 1:
                (gx, gy, gw, gh), (dx, dy, dw, dh) = g[i][1], d[j][0]
                ious.append(v)
                size_err.append((abs(math.log(dw / gw)) + abs(math.log(dh / gh))) / 2)
        for i, (_, gb, cls, vis) in enumerate(g):
            if vis < 0.5:
                continue
            k = "ped" if cls == 1 else "veh"
            tot[k] += 1
            hit[k] += i in used_g
            x, y, w, h = gb
            if k == "veh" and (x < 1 or y < 1 or x + w > size[0] - 1 or y + h > size[1] - 1):
                tot["cut"] += 1
                hit["cut"] += i in used_g
        for j, (_, c) in enumerate(d):
            k = "ped" if c == "pedestrian" else "veh"
            det_n[k] += 1
            det_ok[k] += j in used_d
    rec = {k: hit[k] / tot[k] for k in tot if tot[k]}
    prec = {k: det_ok[k] / det_n[k] for k in det_n if det_n[k]}
    if ious:
        rec["loc"] = sum(ious) / len(ious)
        rec["size"] = sum(size_err) / len(size_err)
    return rec, prec, tot


def mog2(seq, n_frames):
    """OpenCV MOG2 (defaults: history 500, varThreshold 16, shadows detected and dropped),
    3×3 opening and 7×7 closing (as our regions' defaults), external contours, area ≥ 60."""
    sub = cv2.createBackgroundSubtractorMOG2()
    k_open = cv2.getStructuringElement(cv2.MORPH_RECT, (3, 3))
    k_close = cv2.getStructuringElement(cv2.MORPH_RECT, (7, 7))
    dets = defaultdict(list)
    ext = ".jpg"
    with open(f"{seq}/seqinfo.ini") as f:
        for line in f:
            if line.startswith("imExt="):
                ext = line.split("=")[1].strip()
    for frame in range(1, n_frames + 1):
        img = cv2.imread(f"{seq}/img1/{frame:06d}{ext}")
        fg = sub.apply(img)
        fg = np.where(fg == 255, 255, 0).astype(np.uint8)
        fg = cv2.morphologyEx(fg, cv2.MORPH_OPEN, k_open)
        fg = cv2.morphologyEx(fg, cv2.MORPH_CLOSE, k_close)
        contours, _ = cv2.findContours(fg, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
        for c in contours:
            if cv2.contourArea(c) < 60:
                continue
            dets[frame].append(tuple(map(float, cv2.boundingRect(c))))
    return dets


def iou(a, b):
    ax1, ay1, bx1, by1 = a[0] + a[2], a[1] + a[3], b[0] + b[2], b[1] + b[3]
    iw = max(0.0, min(ax1, bx1) - max(a[0], b[0]))
    ih = max(0.0, min(ay1, by1) - max(a[1], b[1]))
    inter = iw * ih
    union = a[2] * a[3] + b[2] * b[3] - inter
    return inter / union if union > 0 else 0.0


def greedy_match(truth_boxes, det_boxes, min_iou):
    """One-to-one matches of truth boxes to detections, best IoU first, down to `min_iou`:
    [(truth index, detection index, IoU)] in the order they were made."""
    pairs = sorted(((iou(gb, db), i, j) for i, gb in enumerate(truth_boxes)
                    for j, db in enumerate(det_boxes)), reverse=True)
    used_g, used_d, out = set(), set(), []
    for v, i, j in pairs:
        if v < min_iou:
            break
        if i in used_g or j in used_d:
            continue
        used_g.add(i)
        used_d.add(j)
        out.append((i, j, v))
    return out


def score(gt, dets, stopped, n_frames):
    hit = defaultdict(int)
    tot = defaultdict(int)
    n_det = n_tp = 0
    for frame in range(1, n_frames + 1):
        g = gt.get(frame, [])
        d = dets.get(frame, [])
        n_det += len(d)
        matches = greedy_match([t[1] for t in g], d, 0.5)
        used_g = {i for i, _, _ in matches}
        n_tp += len(matches)
        for i, (oid, _, cls, vis) in enumerate(g):
            if vis < 0.5:
                continue
            keys = [CLASSES.get(cls, "other"), "all"]
            if cls != 1 and (frame, oid) in stopped[0]:
                keys.append("stopped")
            if cls != 1 and (frame, oid) in stopped[1]:
                keys.append("arrived")
            for k in keys:
                tot[k] += 1
                hit[k] += i in used_g
    rec = {k: hit[k] / tot[k] for k in tot}
    return rec, (n_tp / n_det if n_det else float("nan")), tot


def add_sequence_arguments(ap, seed):
    """The binary and the simulated sequences: what scripts/box_bias.py takes too."""
    ap.add_argument("--roadtrack", default="roadtrack")
    ap.add_argument("--frames", type=int, default=300)
    ap.add_argument("--seed", type=int, default=seed)
    ap.add_argument("--work", default="/tmp/detcmp")
    ap.add_argument("--scenes", default="road,intersection,crossing")
    ap.add_argument("--views", default="aerial,oblique")


def sequence(a, scene, view):
    """The folder of `scene`/`view` at `a.seed` under `a.work`, simulated if missing."""
    seq = f"{a.work}/{scene}_{view}_{a.seed}"
    if not os.path.isdir(seq):
        subprocess.run([a.roadtrack, "-q", "simulate", "--scene", scene, "--view", view,
                        "--frames", str(a.frames), "--seed", str(a.seed), "-o", seq],
                       check=True)
    return seq


def main():
    ap = argparse.ArgumentParser()
    add_sequence_arguments(ap, seed=1)
    ap.add_argument("--cnn-model", default=None)
    ap.add_argument("--cnn-args", default="",
                    help="extra flags for the learned detector, e.g. '--pyramid 1 --min-score 0.4'; "
                         "{seq} stands for the sequence folder, e.g. "
                         "'--zoom-small 12 --calibration {seq}/calibration.toml'")
    ap.add_argument("--config-row", action="append", default=[],
                    help="'name=path.toml [flags]': a background-detector row with --config "
                         "path.toml and any flags; {seq} stands for the sequence folder, e.g. "
                         "'peds=p.toml --calibration {seq}/calibration.toml'")
    ap.add_argument("--recipes", action="store_true",
                    help="the learned detector with each scene's own detect flags, those of its "
                         "pipeline from video (scripts/refine_table.py RECIPES), before "
                         "--cnn-args; needs refine_table's imports (numpy, norfair)")
    ap.add_argument("--only-cnn", action="store_true",
                    help="only the learned detector's rows (no background detectors, no OpenCV)")
    a = ap.parse_args()
    os.makedirs(a.work, exist_ok=True)
    old_cfg = f"{a.work}/old.toml"
    with open(old_cfg, "w") as f:
        f.write(OLD_CONFIG)
    cols = ["all", "car", "lorry/bus", "moto", "ped", "stopped", "arrived"]
    groups = []
    print("| scene | view | detector | " + " | ".join(f"R {c}" for c in cols) + " | P |")
    print("| --- | --- | --- | " + " | ".join("---:" for _ in cols) + " | ---: |")
    for scene in a.scenes.split(","):
        for view in a.views.split(","):
            seq = sequence(a, scene, view)
            gt = read_gt(seq)
            stopped = read_stopped(seq)
            runs = {}
            cal = ["--calibration", f"{seq}/calibration.toml"]
            # (row name, file stem of its detections, flags)
            rows = [] if a.only_cnn else [
                ("median (old)", "median", ["--config", old_cfg]),
                ("default", "default", []),
                ("default + split", "default_split", [*cal, "--split"]),
                ("pedestrians config", "pedestrians", ["--config", PEDESTRIANS_CONFIG, *cal]),
                ("intersection config", "intersection", ["--config", INTERSECTION_CONFIG, *cal]),
            ]
            for row in [] if a.only_cnn else a.config_row:
                name, spec = row.split("=", 1)
                rows.append((name, "row_" + "".join(c if c.isalnum() else "_" for c in name),
                             ["--config", *spec.replace("{seq}", seq).split()]))
            for name, stem, extra in rows:
                out = f"{seq}/det_{stem}.csv"
                subprocess.run([a.roadtrack, "-q", "detect", seq, "-o", out, *extra], check=True)
                runs[name] = read_ours(out)
            if a.cnn_model:
                out = f"{seq}/det_cnn.csv"
                if a.recipes:
                    from refine_table import RECIPES
                    flags = [f.replace("{seq}", seq) for f in RECIPES[f"{scene}-{view}"][1]]
                else:
                    flags = []
                flags += a.cnn_args.replace("{seq}", seq).split()
                subprocess.run([a.roadtrack, "-q", "detect", seq, "-o", out, "--detector", "cnn",
                                "--model", a.cnn_model, *flags], check=True)
                runs["learned (cnn)"] = read_ours(out)
                groups.append((scene, view, score_groups(gt, read_ours(out, True), a.frames,
                                                         frame_size(seq))))
            if not a.only_cnn:
                runs["OpenCV MOG2 + contours"] = mog2(seq, a.frames)
            for name, dets in runs.items():
                rec, prec, tot = score(gt, dets, stopped, a.frames)
                cells = [f"{rec[c]:.2f}" if c in rec else "–" for c in cols]
                print(f"| {scene} | {view} | {name} | " + " | ".join(cells) + f" | {prec:.2f} |",
                      flush=True)
            print(f"<!-- {scene}/{view}: ground-truth counts (visibility ≥ 0.5) "
                  + ", ".join(f"{c} {tot.get(c, 0)}" for c in cols) + " -->", flush=True)


    if groups:
        print()
        print("| scene | view | R vehicles | P vehicles | R pedestrians | P pedestrians "
              "| R vehicles cut by the edge (share) | IoU of found vehicles | size error |")
        print("| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
        f = lambda d, k: f"{d[k]:.2f}" if k in d else "–"
        for scene, view, (rec, prec, tot) in groups:
            share = f" ({tot['cut'] / tot['veh']:.2f})" if tot.get("veh") else ""
            print(f"| {scene} | {view} | {f(rec, 'veh')} | {f(prec, 'veh')} | "
                  f"{f(rec, 'ped')} | {f(prec, 'ped')} | {f(rec, 'cut')}{share} | "
                  f"{f(rec, 'loc')} | {f(rec, 'size')} |")


if __name__ == "__main__":
    main()
