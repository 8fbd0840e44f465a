#!/usr/bin/env bash
# The main job, end to end on a fresh Debian machine with no display: install what is missing,
# build, then run the default scenario (SOFA's liver with a probe) as the demo: real-time
# server, off-screen renderer and a scripted tool over DDS on loopback (scripts/demo.sh).
# Frames, video and timing statistics go to out/demo/. Then, without arguments, the second demo:
# a scalpel incises the liver and the video shows the wound (scripts/demo_incision.sh,
# out/incision/), the third: a grasper turns a suture needle through the liver and out
# (scripts/demo_needle.sh, out/needle/), and the fourth: the same stitch with its thread, pulled
# tight until the incision closes (scripts/demo_suture.sh, out/suture/).
# Usage: scripts/run.sh [SCENARIO [TRAJECTORY]]
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
scripts/build.sh
if [ $# -gt 0 ]; then exec scripts/demo.sh "$@"; fi
scripts/demo.sh
echo
scripts/demo_incision.sh
echo
scripts/demo_needle.sh
echo
exec scripts/demo_suture.sh
