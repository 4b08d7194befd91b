#!/usr/bin/env bash
# The PHD's occlusion-aware p_D (`[detections] occlusion_full_visibility`) against the
# single p_D: HOTA / IDF1 / AssA / MOTA on the public detections of the oblique crossing
# and intersection (300 frames, seeds 1–3), configs/filters-pedestrians.toml with the
# field at 0 (off), 0.3 and 0.5, without and with `--link-gaps 10`. Prints one line per
# scene, setting and gap closing (means; docs/EXPERIMENTS.md "Occlusion-aware p_D").
# Not part of the tests; about 12 min on 2 cores.
set -euo pipefail
cd "$(dirname "$0")/.."
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$HOME/.cache/roadtrack-target}"
cargo build -q --release -p roadtrack-cli
rt="$CARGO_TARGET_DIR/release/roadtrack"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
for v in 0 0.3 0.5; do
  { cat configs/filters-pedestrians.toml
    printf '\n[detections]\nocclusion_full_visibility = %s\n' "$v"; } > "$work/occ-$v.toml"
done
for sv in crossing:oblique intersection:oblique; do
  scene="${sv%%:*}"; view="${sv##*:}"
  for seed in 1 2 3; do
    seq="$work/$scene-$view-$seed"
    "$rt" -q simulate --scene "$scene" --view "$view" --frames 300 --seed "$seed" -o "$seq"
    for v in 0 0.3 0.5; do
      for link in 0 10; do
        "$rt" -q track "$seq" --method phd --detector file --config "$work/occ-$v.toml" \
          --link-gaps "$link" -o "$work/t.txt"
        "$rt" -q evaluate --truth "$seq" --tracks "$work/t.txt" --classes agnostic --json |
          python3 -c 'import json, sys; m = json.load(sys.stdin); print(sys.argv[1], *(f"{m[k]:.4f}" for k in ("HOTA", "IDF1", "AssA", "MOTA")))' \
            "$sv|v_full $v|gaps $link" >> "$work/rows.txt"
      done
    done
  done
done
python3 - "$work/rows.txt" <<'PY'
import sys
from collections import defaultdict
acc = defaultdict(list)
for line in open(sys.argv[1]):
    key, *v = line.rsplit(maxsplit=4)
    acc[key].append([float(x) for x in v])
print("scene | setting | gap closing: HOTA / IDF1 / AssA / MOTA")
for k, rows in acc.items():
    print(k.replace("|", " | "), "|", " / ".join(f"{sum(r[i] for r in rows) / len(rows):.3f}" for i in range(4)))
PY
