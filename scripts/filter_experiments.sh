#!/usr/bin/env bash
# Regenerates docs/EXPERIMENTS.md "Filters on image sequences (seed 004)": the simulator
# tables (PF vs PHD, colour and colour × foreground likelihoods) and the vtest.avi count
# plot docs/img/phd_vtest_count.png and overlay docs/img/phd_vtest_overlay.jpg.
# Usage: scripts/filter_experiments.sh [OUT_DIR] [FRAMES] [SEEDS]   (defaults /tmp/fx 200 3)
# Needs: cargo, ffmpeg (vtest.avi in ../shared/data/). Takes about 12 min (sim) + 1 min
# (vtest) in the dev profile on 2 cores.
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
out="${1:-/tmp/fx}"
frames="${2:-200}"
seeds="${3:-3}"
cd "$here"
cargo build -p roadtrack-cnn --example filter_experiments
bin="${CARGO_TARGET_DIR:-$here/target}/debug/examples/filter_experiments"
"$bin" sim "$out/sim" "$frames" "$seeds"          # → $out/sim/tables.md, runs.json
video="$here/../shared/data/vtest.avi"
if [ -f "$video" ]; then
  "$bin" vtest "$video" "$out/vtest"               # → counts.csv, plot, overlays
  cp "$out/vtest/phd_vtest_count.png" docs/img/phd_vtest_count.png
  ffmpeg -v error -y -i "$out/vtest/overlay_000150.png" -q:v 4 docs/img/phd_vtest_overlay.jpg
else
  echo "note: $video absent, vtest part skipped" >&2
fi
