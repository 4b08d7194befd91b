#!/usr/bin/env bash
# Regenerates docs/img/render_vtest.jpg (docs/VISUALS.md) from ../shared/data/vtest.avi.
#
# The tracks come from a THROWAWAY nearest-neighbour linker of `roadtrack detect` output
# written inline below, only so the picture has something to draw; it is not one of
# roadtrack's trackers. Replace it with `roadtrack track` once the trackers exist.
# Needs: a built roadtrack (cargo build -p roadtrack-cli), python3, ffmpeg.
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
bin="${CARGO_TARGET_DIR:-$here/target}/debug/roadtrack"
video="$here/../shared/data/vtest.avi"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT

"$bin" detect "$video" --end 120 -o "$work/det.csv" -q
python3 - "$work/det.csv" "$work/tracks.txt" <<'PY'
import csv, math, sys
from collections import Counter
rows = list(csv.DictReader(open(sys.argv[1])))
by = {}
for r in rows:
    by.setdefault(int(r["frame"]), []).append(r)
last, nid, out = {}, 0, []
for f in sorted(by):
    dets = by[f]
    pairs = sorted(
        (math.hypot(float(d["x"]) - x, float(d["y"]) - y), t, j)
        for t, (lf, x, y) in last.items() if f - lf <= 5
        for j, d in enumerate(dets)
        if math.hypot(float(d["x"]) - x, float(d["y"]) - y) < 40)
    assigned, taken = {}, set()
    for _, t, j in pairs:
        if t not in taken and j not in assigned:
            assigned[j] = t
            taken.add(t)
    for j, d in enumerate(dets):
        if j not in assigned:
            nid += 1
            assigned[j] = nid
        x, y, w, h = (float(d[k]) for k in ("x", "y", "w", "h"))
        last[assigned[j]] = (f, x, y)
        out.append((f, assigned[j], x - w / 2, y - h / 2, w, h))
n = Counter(t for _, t, *_ in out)
with open(sys.argv[2], "w") as fo:
    for f, t, l, tp, w, h in out:
        if n[t] >= 15:
            fo.write(f"{f},{t},{l:.1f},{tp:.1f},{w:.0f},{h:.0f},1,-1,-1,-1\n")
PY
# All 120 frames: the trails need the frames before the one shown.
"$bin" render "$video" --tracks "$work/tracks.txt" --end 120 -o "$work/frames" -q
mkdir -p "$here/docs/img"
ffmpeg -v error -y -i "$work/frames/000120.png" -q:v 4 "$here/docs/img/render_vtest.jpg"
echo "wrote docs/img/render_vtest.jpg"
