#!/usr/bin/env bash
# The project's test command: formatting, lints, and the whole test suite.
# CI runs exactly this (.ci/run). Build products go outside the clone so repeat runs reuse them.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$HOME/.cache/roadtrack-target}"
export CARGO_TERM_COLOR="${CARGO_TERM_COLOR:-never}"
# A build folder shared by two checkouts (a second clone, a worktree) holds the workspace's
# crates built in the other one, which cargo keeps as fresh here when this checkout's files
# are older, with the other checkout's paths compiled in (`env!("CARGO_MANIFEST_DIR")`:
# the tests' fixtures); if that checkout is gone, its tests fail. So the workspace's own
# crates (not the dependencies) are rebuilt whenever the checkout differs from the last run.
marker="$CARGO_TARGET_DIR/roadtrack-checkout"
here="$(pwd -P)"
if [ "$(cat "$marker" 2>/dev/null)" != "$here" ]; then
  cargo clean --workspace --quiet
  mkdir -p "$CARGO_TARGET_DIR"
  printf '%s\n' "$here" > "$marker"
fi
cargo fmt --all -- --check
cargo clippy --workspace --all-targets --locked -- -D warnings
# The build without tract (`--no-default-features`) must keep compiling: lint it too.
cargo clippy --workspace --all-targets --no-default-features --locked -- -D warnings
cargo test --workspace --locked
