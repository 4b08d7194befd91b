#!/usr/bin/env python3
"""What perfect boxes or identities would be worth (docs/EXPERIMENTS.md "Lorries' boxes",
"What holds the scenes under 0.6"): rewrites a MOT tracks file with each track box that
matches a truth box replaced, in part or whole, by that truth box; frames, scores and
everything else kept. Score the output with `roadtrack evaluate` beside the input: the
difference is what that part of the tracking costs.

    python3 scripts/class_box_oracle.py SEQ TRACKS.txt OUT.txt [--class 6] \\
        [--match best-iou|one-to-one|centre] [--min-iou 0.1] [--radius 1.0] \\
        [--replace box|centre|size|id] [--max-visibility 1.0] [--max-gap N]

--class: only truth boxes of this MOT17 class (1 pedestrian, 3 car, 5 motorcycle, 6 lorry
or bus); every class without it.
--match: `best-iou` (the default) gives each track box the truth box it overlaps most, by
IoU above --min-iou; `one-to-one` pairs track and truth boxes one to one per frame
(Hungarian on IoU, pairs above --min-iou); `centre` one to one on centre distance, pairs
under --radius px (for walkers of 1-2 px, whose boxes a small offset keeps from
overlapping at all).
--replace: `box` (the default) the whole box; `centre` its centre, size kept; `size` its
size, centre kept; `id` the track id (the truth's id, boxes kept; unmatched boxes keep
their track's id, moved out of the truth's range): perfect association of these boxes.
--max-visibility: only truth boxes less visible than this (e.g. 0.5: the occluded ones).
--max-gap: with `--replace id`, a truth id that has no box for more than N frames takes a
new id after the gap: perfect association by a tracker that forgets an object after N
frames without a box (the MRF's `max_missed_frames`).
Not part of the test suite; Python 3 (and scripts/detection_compare.py beside it), scipy
for the one-to-one matches.
"""
import argparse
import os
import sys
from collections import defaultdict

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from detection_compare import iou  # noqa: E402


def read_gt(path):
    gt = defaultdict(list)
    with open(path) as f:
        for line in f:
            c = line.strip().split(",")
            if len(c) < 9 or c[6] == "0":
                continue
            gt[int(c[0])].append((tuple(map(float, c[2:6])), int(c[7]), float(c[8]), int(c[1])))
    return gt


def centre(b):
    return (b[0] + b[2] / 2, b[1] + b[3] / 2)


def matches(rows, truth, a):
    """For each track row index, the truth entry it is paired with."""
    if a.match == "best-iou":
        out = {}
        for i, c in enumerate(rows):
            box = tuple(map(float, c[2:6]))
            best, best_iou = None, a.min_iou
            for t in truth:
                v = iou(t[0], box)
                if v > best_iou:
                    best, best_iou = t, v
            if best is not None:
                out[i] = best
        return out
    if not rows or not truth:
        return {}
    from scipy.optimize import linear_sum_assignment

    boxes = [tuple(map(float, c[2:6])) for c in rows]
    if a.match == "one-to-one":
        cost = [[-iou(t[0], b) for t in truth] for b in boxes]
        ok = lambda v: -v > a.min_iou  # noqa: E731
    else:
        cost = [
            [((centre(t[0])[0] - centre(b)[0]) ** 2 + (centre(t[0])[1] - centre(b)[1]) ** 2) ** 0.5
             for t in truth]
            for b in boxes
        ]
        ok = lambda v: v < a.radius  # noqa: E731
    # Pairs that fail the test cost more than any that pass, so the assignment makes as many
    # good pairs as it can (a plain sum could trade one good pair for two poor ones).
    gated = [[v if ok(v) else 1e6 for v in row] for row in cost]
    r, c = linear_sum_assignment(gated)
    return {i: truth[j] for i, j in zip(r, c) if ok(cost[i][j])}


def split_at_gaps(ids, lines, max_gap, next_id):
    """`ids` (row index -> truth id) with each truth id renumbered after every stretch of
    more than `max_gap` frames in which no row carries it; new ids from `next_id`."""
    by_id = defaultdict(list)
    for k, i in ids.items():
        by_id[i].append((int(lines[k][0]), k))
    out = {}
    for i, rows in sorted(by_id.items()):
        cur, last = i, None
        for frame, k in sorted(rows):
            if last is not None and frame - last > max_gap + 1:
                cur, next_id = next_id, next_id + 1
            out[k], last = cur, frame
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("seq")
    ap.add_argument("tracks")
    ap.add_argument("out")
    ap.add_argument("--class", dest="cls", type=int)
    ap.add_argument("--match", choices=["best-iou", "one-to-one", "centre"], default="best-iou")
    ap.add_argument("--min-iou", type=float, default=0.1)
    ap.add_argument("--radius", type=float, default=1.0)
    ap.add_argument("--replace", choices=["box", "centre", "size", "id"], default="box")
    ap.add_argument("--max-visibility", type=float, default=1.0)
    ap.add_argument("--max-gap", type=int)
    a = ap.parse_args()
    if a.max_gap is not None and a.replace != "id":
        ap.error("--max-gap needs --replace id")
    gt = read_gt(f"{a.seq}/gt/gt.txt")
    lines = []
    frames = defaultdict(list)
    with open(a.tracks) as f:
        for line in f:
            c = line.strip().split(",")
            frames[int(c[0])].append(len(lines))
            lines.append(c)
    first_free = 1 + max((t[3] for ts in gt.values() for t in ts), default=0)
    pair = {}
    for frame, idx in frames.items():
        truth = [
            t for t in gt.get(frame, [])
            if (a.cls is None or t[1] == a.cls)
            and not (a.max_visibility < 1.0 and t[2] >= a.max_visibility)
        ]
        for i, t in matches([lines[k] for k in idx], truth, a).items():
            pair[idx[i]] = t
    ids = {k: t[3] for k, t in pair.items()}
    if a.max_gap is not None:
        ids = split_at_gaps(ids, lines, a.max_gap, first_free + max(
            (int(c[1]) for c in lines), default=0) + 1)
    with open(a.out, "w") as out:
        for k, c in enumerate(lines):
            t = pair.get(k)
            if a.replace == "id":
                c[1] = str(ids[k] if k in ids else first_free + int(c[1]))
            elif t is not None and a.replace == "box":
                c[2:6] = [f"{v:.3f}" for v in t[0]]
            elif t is not None:
                x, y, w, h = map(float, c[2:6])
                cx, cy = x + w / 2, y + h / 2
                if a.replace == "size":
                    w, h = t[0][2], t[0][3]
                else:
                    cx, cy = centre(t[0])
                c[2:6] = [f"{v:.3f}" for v in (cx - w / 2, cy - h / 2, w, h)]
            out.write(",".join(c) + "\n")
    replaced, total = len(pair), len(lines)
    print(f"{a.out}: {replaced} of {total} boxes replaced ({a.replace})")


if __name__ == "__main__":
    main()
