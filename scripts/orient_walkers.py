#!/usr/bin/env python3
"""`--orient-walkers` for a peer's tracks (docs/EXPERIMENTS.md "Walkers' boxes turned to
their walk"): the same rule as roadtrack's box smoothing applies, for MOTChallenge tracks
that carry no class. Each square box under 2.5 px (a `--dots` walker) keeps its centre and
area and becomes the axis-aligned box of a footprint RATIO as deep as it is wide, turned to
the direction of the track's centres fitted by a straight line over N frames on each side;
under MIN_SPEED px per frame the track keeps its last direction. Other boxes pass as they
are.

    python3 scripts/norfair_points.py SEQ D.csv PEER.txt
    python3 scripts/orient_walkers.py PEER.txt PEER_ORIENTED.txt
    roadtrack evaluate --truth SEQ --tracks PEER_ORIENTED.txt --classes agnostic

Not part of the test suite; needs only Python 3.
"""
import argparse
import math
from collections import defaultdict


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("tracks")
    ap.add_argument("out")
    ap.add_argument("--window", type=int, default=5, help="frames on each side (N)")
    ap.add_argument("--min-speed", type=float, default=0.05, help="px per frame")
    ap.add_argument("--ratio", type=float, default=0.65, help="footprint depth / width")
    a = ap.parse_args()
    depth, across = math.sqrt(a.ratio), 1.0 / math.sqrt(a.ratio)
    rows = [line.strip().split(",") for line in open(a.tracks) if line.strip()]
    tracks = defaultdict(dict)
    for r in rows:
        tracks[int(r[1])][int(r[0])] = r
    out = []
    for track in tracks.values():
        heading = None
        for f in sorted(track):
            r = track[f]
            x, y, w, h = map(float, r[2:6])
            if max(w, h) < 2.5 and abs(w - h) < 0.05:
                pts = []
                for g in range(f - a.window, f + a.window + 1):
                    if g in track:
                        gx, gy, gw, gh = map(float, track[g][2:6])
                        pts.append((g, gx + gw / 2, gy + gh / 2))
                if len(pts) >= 3:
                    mt = sum(p[0] for p in pts) / len(pts)
                    den = sum((p[0] - mt) ** 2 for p in pts)
                    vx = sum((p[0] - mt) * p[1] for p in pts) / den
                    vy = sum((p[0] - mt) * p[2] for p in pts) / den
                    if math.hypot(vx, vy) >= a.min_speed:
                        heading = math.atan2(vy, vx)
                if heading is not None:
                    c, s = abs(math.cos(heading)), abs(math.sin(heading))
                    side = math.sqrt(w * h)
                    nw, nh = side * (c * depth + s * across), side * (s * depth + c * across)
                    cx, cy = x + w / 2, y + h / 2
                    r = r[:2] + [f"{cx - nw / 2:.3f}", f"{cy - nh / 2:.3f}", f"{nw:.3f}", f"{nh:.3f}"] + r[6:]
            out.append((f, int(r[1]), ",".join(r)))
    with open(a.out, "w") as fh:
        fh.write("".join(line + "\n" for _, _, line in sorted(out)))


if __name__ == "__main__":
    main()
