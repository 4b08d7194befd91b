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
' "$1" "$work/m.json"
}
echo "| scene | seed | tracker | HOTA | AssA | IDF1 | MOTA | IDSW |"
echo "| --- | ---: | --- | ---: | ---: | ---: | ---: | ---: |"
for sv in road:aerial intersection:oblique crossing:oblique; do
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
