#!/usr/bin/env bash
# Real-time benchmark of docs/REALTIME.md: a scenario served at 1 kHz for DURATION s, a tool
# client commanding at 1 kHz from a script, and (unless --idle) a busy loop on the other core.
# Everything on loopback (the server's default DDS configuration).
# Usage: bench/realtime.sh [DURATION=60] [--idle|--busy] [SCENARIO [TRAJECTORY]]
#        (after scripts/build.sh; default scenarios/liver.yaml with trajectories/liver_press.yaml;
#         the physical scenes: scenarios/physical/liver_16cm.yaml
#         scenarios/trajectories/physical_liver_press.yaml, and so on)
# TOOL_NAME=NAME drives that tool of the scenario (default probe).
# PAUSED=1 starts the server paused and the client resumes it once its first pose is in
# (`stroma tool --resume`): a grasper holding a needle from the first tick.
# TOOL_ARGS="--loop" replays a trajectory that ends where it starts for the whole duration (the
# physical trajectories do); without it the tool holds the script's last pose.
# SERVE_ARGS="..." passes more options to the server (e.g. "--phase-lead-us 0": the fixed
# schedule, for an A/B of the phase lock).
# CRTK=1 serves with --crtk and, after Stroma's own client, runs the same script for the same time
# through the CRTK topics (`stroma tool --crtk`, docs/CRTK.md), so both round trips come from
# one server run, side by side.
# SECOND_TOOL=NAME:SCRIPT drives a second tool of the scenario from its own client at the same
# time (the suture scene's scalpel while TOOL_NAME=grasper holds the needle).
# DDS_CONFIG=FILE passes --dds-config FILE to the server and the client (e.g.
# dds/cyclonedds-loopback.xml: the loopback configuration without real-time receive threads,
# for an A/B of that setting).
set -euo pipefail
cd "$(dirname "$0")/.."
# Loopback only: every DDS participant started here uses Stroma's built-in loopback config,
# never an inherited CYCLONEDDS_URI that could point at another interface or multicast.
unset CYCLONEDDS_URI
dur="${1:-60}"
idle="${2:-}"
scenario="${3:-scenarios/liver.yaml}"
script="${4:-scenarios/trajectories/liver_press.yaml}"
out=$(mktemp -d /tmp/stroma_rt.XXXX)
domain=$(( 150 + RANDOM % 50 ))
hog=""
dds=()
if [ -n "${DDS_CONFIG:-}" ]; then dds=(--dds-config "$DDS_CONFIG"); fi
crtk=()
paused=()
resume=()
if [ -n "${PAUSED:-}" ]; then paused=(--paused); resume=(--resume); fi
serve_for=$((dur + 2))
if [ -n "${CRTK:-}" ]; then crtk=(--crtk); serve_for=$((2 * dur + 4)); fi
if [ "$idle" != "--idle" ]; then
  timeout $((serve_for + 8)) sh -c 'while :; do :; done' & hog=$!
fi
./build/stroma serve "$scenario" "${dds[@]}" "${crtk[@]}" "${paused[@]}" --domain "$domain" --duration "$serve_for" \
  --stats "$out/stats.json" ${SERVE_ARGS:-} > "$out/serve.log" 2>&1 & srv=$!
sleep 1
second=""
if [ -n "${SECOND_TOOL:-}" ]; then
  ./build/stroma tool --name "${SECOND_TOOL%%:*}" --script "${SECOND_TOOL#*:}" "${dds[@]}" --rate 1000 \
    --no-realtime --duration "$dur" --domain "$domain" --out "$out/tool_second.csv" > "$out/tool_second.log" 2>&1 & second=$!
fi
./build/stroma tool --name "${TOOL_NAME:-probe}" --script "$script" "${dds[@]}" "${resume[@]}" ${TOOL_ARGS:-} --rate 1000 \
  --duration "$dur" --domain "$domain" --out "$out/tool.csv" 2> "$out/tool.log" | tee "$out/tool_summary.txt"
if [ -n "${CRTK:-}" ]; then
  ./build/stroma tool --crtk --name "${TOOL_NAME:-probe}" --script "$script" "${dds[@]}" ${TOOL_ARGS:-} --rate 1000 \
    --duration "$dur" --domain "$domain" --out "$out/tool_crtk.csv" 2> "$out/tool_crtk.log" | tee -a "$out/tool_summary.txt"
fi
[ -n "$second" ] && wait $second
wait $srv
[ -n "$hog" ] && kill $hog 2>/dev/null || true
python3 - "$out/stats.json" <<'PY'
import json, sys
j = json.load(open(sys.argv[1]))
w, t = j["wake_latency"], j["tick_time"]
print(f"realtime: {j['realtime']}")
print(f"loops {j['loops']}, ticks {j['ticks']}, missed deadlines {j['missed_deadlines']} ({100*j['missed_ratio']:.3f} %), lag {j['lag']*1e3:.2f} ms")
print(f"wake-up latency us: p50 {w['p50_us']} p99 {w['p99_us']} p99.9 {w['p999_us']} max {w['max_us']:.0f}")
print(f"tick time us:       p50 {t['p50_us']} p99 {t['p99_us']} p99.9 {t['p999_us']} max {t['max_us']:.0f}")
c, pl = j["command_wait"], j["phase_lock"]
print(f"command wait for its tick us: p50 {c['p50_us']} p99 {c['p99_us']} max {c['max_us']:.0f} "
      f"(phase lock lead {pl['lead_us']} us, schedule moved {pl['shift_ms_total']:.3f} ms net)")
print(f"CG iterations mean {j['cg_iterations']['mean']:.1f} max {j['cg_iterations']['max']}; tool commands {j['tool_commands']}")
PY
echo "files in $out"
