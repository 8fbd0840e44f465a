#!/usr/bin/env bash
# The second demo, end to end with no display: a scalpel driven over DDS (`stroma tool --name
# scalpel`) incises the fine 16 cm liver at physical scale, under tension across the incision,
# while `stroma serve` cuts it at 1 kHz and `stroma render` records the incision opening along
# the blade's whole path (the wound's faces drawn as cut tissue). Frames, video and
# statistics (with what was cut: serve_stats.json "cutting") go to out/incision/. Loopback only,
# like every demo. Usage: scripts/demo_incision.sh   (after scripts/build.sh; scripts/run.sh runs it)
set -euo pipefail
cd "$(dirname "$0")/.."
OUT="${OUT:-out/incision}" TOOL_NAME=scalpel \
  exec scripts/demo.sh scenarios/liver_incision_tension.yaml scenarios/trajectories/liver_incision_open.yaml
