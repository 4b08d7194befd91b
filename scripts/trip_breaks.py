#!/usr/bin/env python3
"""Where a demo's trips break (docs/EXPERIMENTS.md "Where the trips break"): for every truth
object that travels from one arm to another, the tracks that cover it frame by frame and how
each change of track came about.

Per frame, truth boxes (sequence/gt/gt.txt) and a method's boxes (METHOD/tracks.txt) are
paired greedily by decreasing IoU, pairs below --iou dropped. A truth object's arm comes from
its ground position in sequence/truth.csv: past --arm-m metres from the centre along the
larger of |x| and |y| (the demo's zones from 12 m, `demo::ARM_START_M`); a trip is a first
arm different from the last. Each change from track A to track B on a trip is counted as

- `fresh`:   B started at most 2 frames before (a new track: the trip is cut in two);
- `stolen`:  B covered another truth object before (an identity swap);
- `resumed`: B existed, covering nothing or this object before (a duplicate or a re-link),

and by what became of A: `A->other` (A went on covering another object) or `A ended`.

    python3 scripts/trip_breaks.py DEMO_DIR [--methods relaxation,mrf,pf,phd] [--iou 0.3]
        [--detail] [--counts]

DEMO_DIR is the output of `roadtrack demo --no-video -o DEMO_DIR`. Prints, per method, the
changes by kind and the trips covered by one track from end to end; with --detail, every
trip's changes. With --counts, also which truth trips the tracks count (docs/EXPERIMENTS.md
"What is left of the turning error, with the floor"): a track's trip is its first and last
arm from its ground positions (METHOD/trajectories.csv, no stitching); it counts the trip
of the truth object it covers in most frames when that object made the same movement and
no other track counted it; per class, the truth trips counted and missed, and the tracks'
trips that count none (a wrong movement, an object that made no trip, a second count).
Not part of the test suite; needs only Python 3 (run from anywhere).
"""
import argparse
import collections
import csv
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from detection_compare import greedy_match  # noqa: E402

KINDS = [(k, a) for k in ("fresh", "stolen", "resumed") for a in ("A->other", "A ended")]


def arm(x, y, arm_m):
    if max(abs(x), abs(y)) < arm_m:
        return None
    if abs(x) >= abs(y):
        return "E" if x > 0 else "W"
    return "N" if y > 0 else "S"


def truth_trips(path, arm_m):
    rows = collections.defaultdict(list)
    cls = {}
    with open(path, newline="") as f:
        for r in csv.DictReader(f):
            rows[int(r["id"])].append((int(r["frame"]), float(r["x_m"]), float(r["y_m"])))
            cls[int(r["id"])] = r["class"]
    return {i: (mv, cls[i]) for i, rs in rows.items() if (mv := movement(rs, arm_m))}


def movement(rows, arm_m):
    """`A→B` for (frame, x_m, y_m) rows whose first arm A differs from their last arm B."""
    arms = [a for a in (arm(x, y, arm_m) for _, x, y in sorted(rows)) if a]
    return arms[0] + "→" + arms[-1] if arms and arms[0] != arms[-1] else None


def read_mot(path):
    frames = collections.defaultdict(list)
    with open(path) as f:
        for line in f:
            v = line.strip().split(",")
            if len(v) >= 6:
                frames[int(v[0])].append((int(v[1]), *map(float, v[2:6])))
    return frames


def coverage(gt, tracks, min_iou):
    """cover[truth][frame] = track, owner[track][frame] = truth, first[track] = frame."""
    cover = collections.defaultdict(dict)
    owner = collections.defaultdict(dict)
    first = {}
    for fr in sorted(set(gt) | set(tracks)):
        for t in tracks.get(fr, []):
            first.setdefault(t[0], fr)
        gs, ts = gt.get(fr, []), tracks.get(fr, [])
        for i, j, _ in greedy_match([g[1:] for g in gs], [t[1:] for t in ts], min_iou):
            cover[gs[i][0]][fr] = ts[j][0]
            owner[ts[j][0]][fr] = gs[i][0]
    return cover, owner, first


def breaks(trip_id, cover, owner, first):
    out = []
    prev, prev_fr = None, None
    for fr, t in sorted(cover[trip_id].items()):
        if t != prev:
            if prev is not None:
                stole = any(g != trip_id for f, g in owner[t].items() if f < fr)
                kind = "fresh" if first[t] >= fr - 2 else ("stolen" if stole else "resumed")
                after = "A->other" if any(f > prev_fr for f in owner[prev]) else "A ended"
                out.append((fr, fr - prev_fr, kind, after))
            prev = t
        prev_fr = fr
    return out


def track_trips(path, arm_m):
    """{track: movement} from a trajectories CSV (frame, id, x_m, y_m)."""
    rows = collections.defaultdict(list)
    with open(path, newline="") as f:
        for r in csv.DictReader(f):
            if r["x_m"] and r["y_m"]:
                rows[int(r["id"])].append((int(r["frame"]), float(r["x_m"]), float(r["y_m"])))
    return {t: mv for t, rs in rows.items() if (mv := movement(rs, arm_m))}


def counted_trips(trips, moves, owner):
    """Per class [truth trips, counted], and the false trips by kind."""
    per = collections.defaultdict(lambda: [0, 0])
    for _, cls in trips.values():
        per[cls][0] += 1
    done, false = set(), collections.Counter()
    for t, mv in sorted(moves.items()):
        cov = collections.Counter(owner[t].values()).most_common(1)
        g = cov[0][0] if cov else None
        if g in trips and trips[g][0] == mv and g not in done:
            done.add(g)
            per[trips[g][1]][1] += 1
        else:
            false["second count" if g in done and trips[g][0] == mv
                  else "wrong movement" if g in trips else "no trip"] += 1
    return per, false


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("demo")
    ap.add_argument("--methods", default="relaxation,mrf,pf,phd")
    ap.add_argument("--iou", type=float, default=0.3)
    ap.add_argument("--arm-m", type=float, default=12.0)
    ap.add_argument("--detail", action="store_true")
    ap.add_argument("--counts", action="store_true")
    a = ap.parse_args()
    seq = os.path.join(a.demo, "sequence")
    trips = truth_trips(os.path.join(seq, "truth.csv"), a.arm_m)
    gt = read_mot(os.path.join(seq, "gt", "gt.txt"))
    print(f"{a.demo}: {len(trips)} truth trips")
    print("| method | " + " | ".join(f"{k} / {w}" for k, w in KINDS)
          + " | changes | trips with one track |")
    print("| --- |" + " ---: |" * (len(KINDS) + 2))
    for m in a.methods.split(","):
        cover, owner, first = coverage(gt, read_mot(os.path.join(a.demo, m, "tracks.txt")), a.iou)
        count = collections.Counter()
        whole = 0
        lines = []
        for g, (mv, cls) in sorted(trips.items()):
            b = breaks(g, cover, owner, first)
            count.update((k, w) for _, _, k, w in b)
            whole += not b and bool(cover[g])
            lines.append(f"  {g} {cls} {mv}: " + (", ".join(
                f"@{fr} gap {gap} {k} / {w}" for fr, gap, k, w in b) or "one track"))
        print(f"| {m} | " + " | ".join(str(count[k]) for k in KINDS)
              + f" | {sum(count.values())} | {whole} / {len(trips)} |")
        if a.detail:
            print("\n".join(lines))
        if a.counts:
            moves = track_trips(os.path.join(a.demo, m, "trajectories.csv"), a.arm_m)
            per, false = counted_trips(trips, moves, owner)
            print(f"  {m} counts: " + ", ".join(
                f"{c} {n[1]}/{n[0]}" for c, n in sorted(per.items()))
                + f"; false trips: {sum(false.values())} " + str(dict(sorted(false.items()))))


if __name__ == "__main__":
    main()
