#!/usr/bin/env bash
# The main job, end to end on a fresh Debian machine: install what is missing, build, and run
# the default scenario (SOFA's liver demo at 1 kHz) headless. Results go to out/liver/.
# Usage: scripts/run.sh [SCENARIO] [stroma run options...]
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
scripts/build.sh
scenario="${1:-scenarios/liver.yaml}"
shift || true
./build/stroma run "$scenario" "$@"
