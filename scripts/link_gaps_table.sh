#!/usr/bin/env bash
# Offline gap closing (`track --link-gaps N`) against none, every method on the public
# detections of the six simulated scenes (300 frames, seeds 1–3; relaxation with
# configs/relaxation-video.toml, pf and phd with configs/filters-pedestrians.toml), then
# the PHD on the crossing over four filter seeds. Prints markdown tables of the means
# (docs/TRACKING.md "Gap closing"). Not part of the tests; about 15 min on 2 cores.
#
#   scripts/link_gaps_table.sh [GAP]        # default 10
#   scripts/link_gaps_table.sh GAP COLOUR   # --link-gaps GAP against the same with
#                                           # --link-colour COLOUR (docs/TRACKING.md)
set -euo pipefail
cd "$(dirname "$0")/.."
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$HOME/.cache/roadtrack-target}"
cargo build -q --release -p roadtrack-cli
rt="$CARGO_TARGET_DIR/release/roadtrack"
gap="${1:-10}"
colour="${2:-}"
# The two settings compared: labels "0" (before) and "$gap" (after).
with() { # label → flags
  if [ -z "$colour" ]; then echo --link-gaps "$1"
  elif [ "$1" = 0 ]; then echo --link-gaps "$gap"
  else echo --link-gaps "$gap" --link-colour "$colour"; fi
}
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
score() { # seq tracks label
  "$rt" -q evaluate --truth "$1" --tracks "$2" --classes agnostic --json |
    python3 -c 'import json, sys; m = json.load(sys.stdin); print(sys.argv[1], *(f"{m[k]:.4f}" for k in ("HOTA", "IDF1", "AssA", "MOTA")))' "$3"
}
for sv in road:aerial road:oblique intersection:aerial intersection:oblique crossing:aerial crossing:oblique; do
  scene="${sv%%:*}"; view="${sv##*:}"
  for seed in 1 2 3; do
    seq="$work/$scene-$view-$seed"
    "$rt" -q simulate --scene "$scene" --view "$view" --frames 300 --seed "$seed" -o "$seq"
    for method in relaxation mrf pf phd; do
      case $method in
        relaxation) cfg=(--config configs/relaxation-video.toml) ;;
        pf | phd) cfg=(--config configs/filters-pedestrians.toml) ;;
        *) cfg=() ;;
      esac
      for link in 0 "$gap"; do
        "$rt" -q track "$seq" --method "$method" --detector file "${cfg[@]}" \
          $(with "$link") -o "$work/t.txt"
        score "$seq" "$work/t.txt" "$scene/$view|$method|$link" >> "$work/rows.txt"
      done
    done
    if [ "$sv" = crossing:oblique ]; then
      for fseed in 11 12 13; do
        for link in 0 "$gap"; do
          "$rt" -q track "$seq" --method phd --detector file \
            --config configs/filters-pedestrians.toml --seed "$fseed" \
            $(with "$link") -o "$work/t.txt"
          score "$seq" "$work/t.txt" "filter seed $fseed|phd|$link" >> "$work/rows.txt"
        done
      done
    fi
  done
done
after="--link-gaps $gap"
[ -n "$colour" ] && after="--link-gaps $gap --link-colour $colour"
before="none"
[ -n "$colour" ] && before="--link-gaps $gap"
python3 - "$work/rows.txt" "$gap" "$before" "$after" <<'PY'
import sys
from collections import defaultdict
acc = defaultdict(list)
for line in open(sys.argv[1]):
    key, *v = line.rsplit(maxsplit=4)
    acc[tuple(key.split("|"))].append([float(x) for x in v])
mean = {k: [sum(r[i] for r in rows) / len(rows) for i in range(4)] for k, rows in acc.items()}
print(f"| scene | method | HOTA, {sys.argv[3]} | IDF1 | AssA | MOTA | HOTA, {sys.argv[4]} | IDF1 | AssA | MOTA |")
print("| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
for (sv, m, link), a in mean.items():
    if link != "0":
        continue
    b = mean[(sv, m, sys.argv[2])]
    print(f"| {sv} | {m} | " + " | ".join(f"{x:.3f}" for x in a + b) + " |")
PY
