#!/usr/bin/env bash
# The suture demo, end to end with no display: the needle demo (scripts/demo_needle.sh) with a
# suture thread tied to the needle's tail and anchored in the near lip. A scalpel (`stroma tool
# --name scalpel`) incises the fine 16 cm liver, which gapes (it is under tension across the
# incision); a grasper (`stroma tool --name grasper`) turns the needle through both lips and out,
# the thread following it through the four punctures, then pulls the needle on up and away: the
# thread draws tight and the lips close at the stitch — while `stroma serve` steps it all at 1 kHz
# and `stroma render` records it (the thread a violet tube). The server starts paused and the
# grasper's client resumes it once its jaws are closed on the needle. Frames, video and
# statistics go to out/suture/. Loopback only, like every demo. Usage: scripts/demo_suture.sh
# (after scripts/build.sh; scripts/run.sh runs it). The scenario and its scripts:
# scenarios/liver_suture_thread.yaml; the closure it shows is tested headless
# (WoundClosure.OneStitchPulledToItsTensionClosesTheIncisionAndHoldsIt, docs/THREAD.md).
set -euo pipefail
cd "$(dirname "$0")/.."
if [ "${1:-}" = "--help" ] || [ "${1:-}" = "-h" ]; then
  sed -n '2,13p' "$0" | sed 's/^# \{0,1\}//'
  exit 0
fi
OUT="${OUT:-out/suture}" TOOL_NAME=grasper SECOND_TOOL=scalpel:scenarios/trajectories/liver_suture_scalpel.yaml \
  SERVE_ARGS="--paused ${SERVE_ARGS:-}" TOOL_ARGS="--resume ${TOOL_ARGS:-}" \
  exec scripts/demo.sh scenarios/liver_suture_thread.yaml scenarios/trajectories/liver_suture_thread_grasper.yaml
