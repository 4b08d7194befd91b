#!/usr/bin/env python3
"""roadtrack's box smoothing for walkers seen from above, for a peer's tracks
(docs/EXPERIMENTS.md "Walkers' boxes turned to their walk"). MOTChallenge tracks carry no
class, so a walker is a square box under 2.5 px (a `--dots` box). For each such box:

- without --window: the box keeps its centre; its direction is the slope of a straight
  line fitted to its track's centres over 5 frames on each side;
- with --window N: the centre too becomes that line's value, fitted over N frames on each
  side, by least squares or, with --robust, by Huber's M-estimate (k = 1.345 robust
  scales of the residuals, 10 reweightings), as `roadtrack track --smooth-boxes N
  [--smooth-robust]`; the size by least squares;

then the box keeps its area and becomes the axis-aligned box of a footprint RATIO as deep
as it is wide turned to that direction (`--orient-walkers`); under MIN_SPEED px per frame
the track keeps its last direction. Other boxes pass as they are. With --min-rows N a
track with fewer than N boxes is left out, as `roadtrack track --confirm-hits N` writes
only a track seen in N frames.

    python3 scripts/norfair_points.py SEQ D.csv PEER.txt
    python3 scripts/orient_walkers.py PEER.txt OUT.txt [--window 12 --robust] [--min-rows 32]
    roadtrack evaluate --truth SEQ --tracks OUT.txt --classes agnostic

Not part of the test suite; needs only Python 3.
"""
import argparse
import math
from collections import defaultdict


def line(ts, ys, ws):
    """Weighted least squares of y = a + b t: (a, b)."""
    sw = sum(ws)
    mt = sum(w * t for t, w in zip(ts, ws)) / sw
    my = sum(w * y for y, w in zip(ys, ws)) / sw
    stt = sum(w * (t - mt) ** 2 for t, w in zip(ts, ws))
    sty = sum(w * (t - mt) * (y - my) for t, y, w in zip(ts, ys, ws))
    b = sty / stt if stt > 0 else 0.0
    return my - b * mt, b


def median(v):
    v = sorted(v)
    n = len(v)
    return v[n // 2] if n % 2 else 0.5 * (v[n // 2 - 1] + v[n // 2])


def huber_line(ts, ys, k=1.345):
    ws = [1.0] * len(ts)
    a, b = line(ts, ys, ws)
    for _ in range(10):
        res = [y - (a + b * t) for t, y in zip(ts, ys)]
        m = median(res)
        c = k * max(1.4826 * median([abs(r - m) for r in res]), 0.02)
        ws = [1.0 if abs(r) <= c else c / abs(r) for r in res]
        a, b = line(ts, ys, ws)
    return a, b


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("tracks")
    ap.add_argument("out")
    ap.add_argument("--window", type=int, default=0, help="refit centres over N frames each side")
    ap.add_argument("--robust", action="store_true", help="Huber fit of the centres")
    ap.add_argument("--min-speed", type=float, default=0.05, help="px per frame")
    ap.add_argument("--ratio", type=float, default=0.65, help="footprint depth / width")
    ap.add_argument("--min-rows", type=int, default=0, help="leave out tracks with fewer boxes")
    a = ap.parse_args()
    depth, across = math.sqrt(a.ratio), 1.0 / math.sqrt(a.ratio)
    rows = [line_.strip().split(",") for line_ in open(a.tracks) if line_.strip()]
    tracks = defaultdict(dict)
    for r in rows:
        tracks[int(r[1])][int(r[0])] = r
    out = []
    for track in tracks.values():
        if len(track) < a.min_rows:
            continue
        heading = None
        for f in sorted(track):
            r = track[f]
            x, y, w, h = map(float, r[2:6])
            if max(w, h) < 2.5 and abs(w - h) < 0.05:
                n = a.window or 5
                pts = []
                for g in range(f - n, f + n + 1):
                    if g in track:
                        gx, gy, gw, gh = map(float, track[g][2:6])
                        pts.append((g - f, gx + gw / 2, gy + gh / 2, gw, gh))
                cx, cy = x + w / 2, y + h / 2
                if len(pts) >= 3:
                    ts = [p[0] for p in pts]
                    fit = huber_line if a.robust else (lambda t, v: line(t, v, [1.0] * len(t)))
                    (ax, vx), (ay, vy) = fit(ts, [p[1] for p in pts]), fit(ts, [p[2] for p in pts])
                    if a.window:
                        ones = [1.0] * len(ts)
                        fw, fh = line(ts, [p[3] for p in pts], ones)[0], line(ts, [p[4] for p in pts], ones)[0]
                        if fw <= 0 or fh <= 0:
                            # As roadtrack: a fit with no size leaves the box as it is.
                            out.append((f, int(r[1]), ",".join(r)))
                            continue
                        cx, cy, w, h = ax, ay, fw, fh
                    if math.hypot(vx, vy) >= a.min_speed:
                        heading = math.atan2(vy, vx)
                if heading is not None:
                    c, s = abs(math.cos(heading)), abs(math.sin(heading))
                    side = math.sqrt(w * h)
                    w, h = side * (c * depth + s * across), side * (s * depth + c * across)
                r = r[:2] + [f"{cx - w / 2:.3f}", f"{cy - h / 2:.3f}", f"{w:.3f}", f"{h:.3f}"] + r[6:]
            out.append((f, int(r[1]), ",".join(r)))
    with open(a.out, "w") as fh:
        fh.write("".join(line_ + "\n" for _, _, line_ in sorted(out)))


if __name__ == "__main__":
    main()
