#!/usr/bin/env bash
# Trackers on the same public detections (det/det.txt) of simulated scenes: norfair's IoU
# tracker (scripts/norfair_peer.py) beside every roadtrack method as published
# (--as-published) and with the shared life cycle (the filters: detections as
# measurements), relaxation with configs/relaxation-video.toml, and the filters
# with configs/filters-pedestrians.toml. Class-agnostic HOTA, AssA, IDF1, MOTA, IDSW by
# `roadtrack evaluate` (TrackEval's definitions). Prints a markdown table (docs/TRACKING.md).
#
#   scripts/tracking_table.sh [FRAMES] [SEEDS...]      # default 300 frames, seeds 1 2 3
#
# SCENES="road:aerial crossing:oblique" limits the scene/view pairs (default: all six).
# After the per-seed rows it prints the means over the seeds and, per scene, the best
# roadtrack row against norfair.
#
# Needs norfair in the Python that PYTHON names (default python3); not part of the tests.
set -euo pipefail
cd "$(dirname "$0")/.."
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$HOME/.cache/roadtrack-target}"
py="${PYTHON:-python3}"
cargo build -q --release -p roadtrack-cli
rt="$CARGO_TARGET_DIR/release/roadtrack"
frames="${1:-300}"
shift || true
seeds=("$@")
[ ${#seeds[@]} -eq 0 ] && seeds=(1 2 3)
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
row() { # label seq tracks
  "$rt" -q evaluate --truth "$2" --tracks "$3" --classes agnostic --json > "$work/m.json"
  "$py" -c '
import json, sys
m = json.load(open(sys.argv[2]))
cells = [f"{m[k]:.3f}" for k in ("HOTA", "AssA", "IDF1", "MOTA")] + [str(int(m["IDSW"]))]
print(sys.argv[1] + " | " + " | ".join(cells) + " |")
' "$1" "$work/m.json" | tee -a "$work/rows.md"
}
echo "| scene | seed | tracker | HOTA | AssA | IDF1 | MOTA | IDSW |"
echo "| --- | ---: | --- | ---: | ---: | ---: | ---: | ---: |"
scenes="${SCENES:-road:aerial road:oblique intersection:aerial intersection:oblique crossing:aerial crossing:oblique}"
for sv in $scenes; do
  scene="${sv%%:*}"; view="${sv##*:}"
  for seed in "${seeds[@]}"; do
    seq="$work/$scene-$view-$seed"
    "$rt" -q simulate --scene "$scene" --view "$view" --frames "$frames" --seed "$seed" -o "$seq"
    at="| $scene/$view | $seed"
    "$py" scripts/norfair_peer.py "$seq" "$work/t.txt"
    row "$at | norfair IoU (peer)" "$seq" "$work/t.txt"
    for method in relaxation mrf pf phd; do
      "$rt" -q track "$seq" --method "$method" --detector file --as-published -o "$work/t.txt"
      row "$at | $method, as published" "$seq" "$work/t.txt"
      "$rt" -q track "$seq" --method "$method" --detector file -o "$work/t.txt"
      row "$at | $method, shared life cycle" "$seq" "$work/t.txt"
    done
    "$rt" -q track "$seq" --method relaxation --detector file \
      --config configs/relaxation-video.toml -o "$work/t.txt"
    row "$at | relaxation, life cycle + relaxation-video.toml" "$seq" "$work/t.txt"
    for method in pf phd; do
      "$rt" -q track "$seq" --method "$method" --detector file \
        --config configs/filters-pedestrians.toml -o "$work/t.txt"
      row "$at | $method, detections + filters-pedestrians.toml" "$seq" "$work/t.txt"
    done
  done
done
echo
"$py" - "$work/rows.md" <<'PY'
import sys
from collections import defaultdict
acc = defaultdict(list)
for line in open(sys.argv[1]):
    c = [x.strip() for x in line.strip().strip("|").split("|")]
    acc[(c[0], c[2])].append([float(x) for x in c[3:8]])
print("Means over the seeds:\n")
print("| scene | tracker | HOTA | AssA | IDF1 | MOTA | IDSW |")
print("| --- | --- | ---: | ---: | ---: | ---: | ---: |")
mean = {}
for (sv, t), rows in acc.items():
    mean[(sv, t)] = [sum(r[i] for r in rows) / len(rows) for i in range(5)]
    m = mean[(sv, t)]
    print(f"| {sv} | {t} | {m[0]:.3f} | {m[1]:.3f} | {m[2]:.3f} | {m[3]:.3f} | {m[4]:.1f} |")
print("\n| scene | norfair HOTA / IDF1 | best roadtrack | HOTA / IDF1 |")
print("| --- | ---: | --- | ---: |")
for sv in dict.fromkeys(sv for sv, _ in acc):
    p = mean[(sv, "norfair IoU (peer)")]
    best = max((m[0], t) for (s, t), m in mean.items() if s == sv and "peer" not in t)
    b = mean[(sv, best[1])]
    print(f"| {sv} | {p[0]:.3f} / {p[2]:.3f} | {best[1]} | {b[0]:.3f} / {b[2]:.3f} |")
PY
