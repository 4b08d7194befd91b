#!/usr/bin/env bash
# Installs what roadtrack needs beyond Rust: ffmpeg (video input) from Debian's packages.
# Idempotent; does nothing when ffmpeg and ffprobe are already on PATH.
set -euo pipefail

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
