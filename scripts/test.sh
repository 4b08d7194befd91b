#!/usr/bin/env bash
# The project's test command: formatting, lints, and the whole test suite.
# CI runs exactly this (.ci/run). Build products go outside the clone so repeat runs reuse them.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$HOME/.cache/roadtrack-target}"
export CARGO_TERM_COLOR="${CARGO_TERM_COLOR:-never}"
cargo fmt --all -- --check
cargo clippy --workspace --all-targets --locked -- -D warnings
# The build without tract (`--no-default-features`) must keep compiling: lint it too.
cargo clippy --workspace --all-targets --no-default-features --locked -- -D warnings
cargo test --workspace --locked
