#!/usr/bin/env bash
# The main job, end to end, with no display: `stroma serve` runs the scenario at 1 kHz,
# `stroma render` records off-screen frames (PNG + MP4), and `stroma tool --script` presses,
# slides and grasps the tissue for about 5.5 s; then all three stop cleanly and the script
# prints where the frames, the video and the timing statistics are. Every DDS participant is on
# loopback only (the built-in default). The scripted tool runs under SCHED_FIFO, as a haptic
# bridge would (without locking its memory: that stalled the renderer); TOOL_ARGS=--no-realtime
# runs it at normal priority.
# Usage: scripts/demo.sh [SCENARIO [TRAJECTORY]]   (run scripts/build.sh first; scripts/run.sh does)
# Environment: OUT (default out/demo), STROMA_DOMAIN (default 7), FPS (30), SIZE (640x480),
# TOOL_NAME (the scenario's tool the script drives; default probe),
# SERVE_ARGS (more options for `stroma serve`, e.g. "--phase-lead-us 0"), TOOL_ARGS (for
# `stroma tool`, e.g. "--no-realtime"), SECOND_TOOL ("NAME:TRAJECTORY": a second client, started
# just before the first, drives that tool at the same time — two instruments, two clients).
set -euo pipefail
cd "$(dirname "$0")/.."
# Loopback only: every DDS participant started here uses Stroma's built-in loopback config,
# never an inherited CYCLONEDDS_URI that could point at another interface or multicast.
unset CYCLONEDDS_URI

scenario="${1:-scenarios/liver.yaml}"
trajectory="${2:-scenarios/trajectories/liver_demo.yaml}"
out="${OUT:-out/demo}"
domain="${STROMA_DOMAIN:-7}"
fps="${FPS:-30}"
size="${SIZE:-640x480}"
tool_name="${TOOL_NAME:-probe}"
width="${size%x*}"
height="${size#*x}"
stroma=./build/stroma
[ -x "$stroma" ] || { echo "demo: $stroma not found: run scripts/build.sh first" >&2; exit 2; }
[ -f "$scenario" ] || { echo "demo: scenario '$scenario' not found" >&2; exit 2; }
[ -f "$trajectory" ] || { echo "demo: trajectory '$trajectory' not found" >&2; exit 2; }

rm -rf "$out"
mkdir -p "$out"
pids=()
cleanup() {
  for p in "${pids[@]}"; do kill -INT "$p" 2>/dev/null || true; done
  wait 2>/dev/null || true
}
trap cleanup EXIT

# The tool script's length decides how long to record (plus a second to see the tissue settle).
script_length() { awk '/t:/ { sub(/.*t: */, ""); sub(/[,}].*/, ""); t = $0 } END { print t + 0 }' "$1"; }
script_s=$(script_length "$trajectory")
second_name="" second_trajectory="" second_pid=""
if [ -n "${SECOND_TOOL:-}" ]; then
  second_name="${SECOND_TOOL%%:*}"
  second_trajectory="${SECOND_TOOL#*:}"
  [ -f "$second_trajectory" ] || { echo "demo: SECOND_TOOL's trajectory '$second_trajectory' not found" >&2; exit 2; }
  script_s=$(awk -v a="$script_s" -v b="$(script_length "$second_trajectory")" 'BEGIN { print (a > b ? a : b) }')
fi
record_s=$(awk -v t="$script_s" 'BEGIN { print t + 1.5 }')

echo "demo: serving $scenario on DDS domain $domain (loopback only)"
"$stroma" serve "$scenario" --domain "$domain" --stats "$out/serve_stats.json" --duration 120 \
  ${SERVE_ARGS:-} > "$out/serve.log" 2>&1 &
pids+=($!)
echo "demo: recording ${width}x${height} at $fps FPS into $out/frames"
"$stroma" render --domain "$domain" --out "$out/frames" --video "$out/demo.mp4" --fps "$fps" \
  --width "$width" --height "$height" --duration "$record_s" --wait 30 \
  --stats "$out/render_stats.json" > "$out/render.log" 2>&1 &
render_pid=$!
pids+=($render_pid)

# Start the tool once the renderer records (it has the mesh and a first state).
for _ in $(seq 1 300); do
  grep -q "recording" "$out/render.log" 2>/dev/null && break
  kill -0 "$render_pid" 2>/dev/null || break
  sleep 0.1
done
if ! grep -q "recording" "$out/render.log"; then
  echo "demo: the renderer did not start; its log:" >&2
  cat "$out/render.log" "$out/serve.log" >&2
  exit 1
fi
if [ -n "$second_name" ]; then
  echo "demo: driving the $second_name with $second_trajectory"
  "$stroma" tool --name "$second_name" --script "$second_trajectory" --domain "$domain" --out "$out/tool_$second_name.csv" \
    --no-realtime > "$out/tool_$second_name.log" 2>&1 &
  second_pid=$!
  pids+=($second_pid)
fi
echo "demo: driving the tool with $trajectory (${script_s} s)"
"$stroma" tool --name "$tool_name" --script "$trajectory" --domain "$domain" --out "$out/tool.csv" ${TOOL_ARGS:-} \
  > "$out/tool.log" 2>&1 || { echo "demo: the tool client failed:" >&2; cat "$out/tool.log" >&2; exit 1; }

[ -z "$second_pid" ] || wait "$second_pid" || { echo "demo: the $second_name's client failed:" >&2; cat "$out/tool_$second_name.log" >&2; exit 1; }
status=0
wait "$render_pid" || status=$?
kill -INT "${pids[0]}" 2>/dev/null || true
wait "${pids[0]}" || true
pids=()
if [ "$status" -ne 0 ]; then
  echo "demo: the renderer failed (exit $status); its log:" >&2
  cat "$out/render.log" >&2
  exit 1
fi

frames=$(find "$out/frames" -name 'frame_*.png' | wc -l)
echo
echo "server:   $(grep -E 'ticks in' "$out/serve.log" | sed 's/^\[[^]]*\] \[[^]]*\] //')"
echo "tool:     $(grep -E "^tool '" "$out/tool.log")"
echo "renderer: $(grep -E 'frames written' "$out/render.log" | sed 's/^\[[^]]*\] \[[^]]*\] //')"
echo
echo "frames:   $out/frames/ ($frames PNG files, frames.csv)"
[ -f "$out/demo.mp4" ] && echo "video:    $out/demo.mp4"
echo "stats:    $out/serve_stats.json (physics), $out/render_stats.json (frames), $out/tool.csv (force feedback, round trips)"
echo "logs:     $out/serve.log $out/render.log $out/tool.log"
