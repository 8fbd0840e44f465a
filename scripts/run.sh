#!/usr/bin/env bash
# The main job, end to end on a fresh Debian machine with no display: install what is missing,
# build, then run the default scenario (SOFA's liver with a probe) as the demo: real-time
# server, off-screen renderer and a scripted tool over DDS on loopback (scripts/demo.sh).
# Frames, video and timing statistics go to out/demo/.
# Usage: scripts/run.sh [SCENARIO [TRAJECTORY]]
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
scripts/build.sh
exec scripts/demo.sh "$@"
