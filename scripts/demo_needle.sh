#!/usr/bin/env bash
# The needle demo, end to end with no display: a grasper driven over DDS (`stroma tool --name
# grasper`) turns a half-circle suture needle through the 16 cm liver's upper surface and out,
# holds it and turns it back, while `stroma serve` steps it at 1 kHz and `stroma render` records
# it (the needle a steel tube, its track's points dark marks). The server starts paused and the
# client resumes it once its jaws are closed on the needle (`stroma tool --resume`), so the
# needle is held from the first tick. Frames, video and statistics go to out/needle/. Loopback
# only, like every demo. Usage: scripts/demo_needle.sh   (after scripts/build.sh; scripts/run.sh
# runs it)
set -euo pipefail
cd "$(dirname "$0")/.."
OUT="${OUT:-out/needle}" TOOL_NAME=grasper SERVE_ARGS="--paused ${SERVE_ARGS:-}" TOOL_ARGS="--resume ${TOOL_ARGS:-}" \
  exec scripts/demo.sh scenarios/physical/liver_16cm_needle.yaml scenarios/trajectories/physical_liver_needle_turn.yaml
