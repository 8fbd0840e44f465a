#!/usr/bin/env bash
# The needle demo, end to end with no display: two instruments, two DDS clients. A scalpel
# (`stroma tool --name scalpel`) incises the fine 16 cm liver while a grasper (`stroma tool
# --name grasper`) holds a half-circle suture needle aside; then the grasper turns the needle
# across the incision — in through one lip's surface, out of its cut face, into the other lip's
# and out — lets go of it, regrasps it near the tip where it came out and turns it on through,
# while `stroma serve` steps it all at 1 kHz and `stroma render` records it (the needle a steel
# tube, its track's points dark marks, the wound's faces cut tissue). The server starts paused
# and the grasper's client resumes it once its jaws are closed on the needle (`stroma tool
# --resume`), so the needle is held from the first tick. Frames, video and statistics go to
# out/needle/. Loopback only, like every demo. Usage: scripts/demo_needle.sh   (after
# scripts/build.sh; scripts/run.sh runs it). The scenario and its scripts: scenarios/liver_suture.yaml.
set -euo pipefail
cd "$(dirname "$0")/.."
OUT="${OUT:-out/needle}" TOOL_NAME=grasper SECOND_TOOL=scalpel:scenarios/trajectories/liver_suture_scalpel.yaml \
  SERVE_ARGS="--paused ${SERVE_ARGS:-}" TOOL_ARGS="--resume ${TOOL_ARGS:-}" \
  exec scripts/demo.sh scenarios/liver_suture.yaml scenarios/trajectories/liver_suture_grasper.yaml
