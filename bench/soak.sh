#!/usr/bin/env bash
# Soak: the demo's three processes for MINUTES — `stroma serve` on the liver at 1 kHz,
# `stroma render` at 30 FPS (PNG frames, no video: a long soak would fill the disk; frames are
# deleted as they come, keeping the last 100), `stroma tool` at 1 kHz looping a press, slide,
# grasp and release (scenarios/trajectories/liver_soak.yaml) — all on loopback. Reports:
#  - each process's resident memory over time (sampled every 10 s into rss.csv) and its growth
#    after a warm-up (the first fifth of the run, at least 30 s): flat means within 1 %;
#  - the server's missed deadlines, the tool's round trip p50/p99/max, the renderer's drops.
# Exits 1 if a process dies, the memory grows by more than 1 % after warm-up, or the tool sees
# no feedback. With LSAN=1 (binaries built with -fsanitize=address: BUILD=build-asan-full, preset
# asan-full) LeakSanitizer's report of each process at exit is the check instead of the memory
# growth (ASan's quarantine grows by design); no real-time scheduling then.
# Usage: bench/soak.sh [MINUTES=60]    Environment: OUT (default out/soak), STROMA_DOMAIN (37),
#        BUILD (default build).
set -euo pipefail
cd "$(dirname "$0")/.."
unset CYCLONEDDS_URI  # loopback only: Stroma's built-in configuration
if [ "${1:-}" = "-h" ] || [ "${1:-}" = "--help" ]; then sed -n '2,14p' "$0" | sed 's/^# \{0,1\}//'; exit 0; fi
minutes="${1:-60}"
out="${OUT:-out/soak}"
domain="${STROMA_DOMAIN:-37}"
stroma="${BUILD:-build}/stroma"
[ -x "$stroma" ] || { echo "soak: $stroma not found: run scripts/build.sh first" >&2; exit 2; }
secs=$(awk -v m="$minutes" 'BEGIN { printf "%d", m * 60 }')
[ "$secs" -ge 30 ] || { echo "soak: at least 0.5 minutes" >&2; exit 2; }
rm -rf "$out"
mkdir -p "$out/frames"
# Under the sanitizers no real-time scheduling or locked memory (ASan's shadow is terabytes of
# address space: mlockall would try to lock it).
rt_serve=(); rt_tool=()
if [ "${LSAN:-0}" = 1 ]; then rt_serve=(--realtime off); rt_tool=(--no-realtime); fi
pids=()
cleanup() { for p in "${pids[@]}"; do kill -INT "$p" 2>/dev/null || true; done; wait 2>/dev/null || true; }
trap cleanup EXIT

"$stroma" serve scenarios/liver.yaml --domain "$domain" --duration $((secs + 30)) --stats "$out/serve_stats.json" "${rt_serve[@]}" \
  > "$out/serve.log" 2>&1 &
server=$!; pids+=($server)
"$stroma" render --domain "$domain" --out "$out/frames" --no-video --fps 30 --width 320 --height 240 \
  --duration "$secs" --wait 30 --stats "$out/render_stats.json" > "$out/render.log" 2>&1 &
renderer=$!; pids+=($renderer)
sleep 2
"$stroma" tool --name probe --script scenarios/trajectories/liver_soak.yaml --loop --duration "$secs" \
  --domain "$domain" --out "$out/tool.csv" "${rt_tool[@]}" > "$out/tool.log" 2>&1 &
tool=$!; pids+=($tool)

rss() { awk '/VmRSS/ { print $2 }' "/proc/$1/status" 2>/dev/null || echo 0; }
echo "t_s,server_kb,renderer_kb,tool_kb" > "$out/rss.csv"
start=$(date +%s)
while kill -0 "$tool" 2>/dev/null; do
  now=$(( $(date +%s) - start ))
  echo "$now,$(rss $server),$(rss $renderer),$(rss $tool)" >> "$out/rss.csv"
  # Keep the disk flat: the frames of the last ~3 s only.
  { ls -1 "$out/frames"/frame_*.png 2>/dev/null || true; } | head -n -100 | xargs -r rm -f
  [ $((now % 60)) -lt 10 ] && echo "soak: ${now} s of ${secs} s" >&2
  sleep 10
done
status=0
wait "$tool" || status=1
wait "$renderer" || status=1
kill -INT "$server" 2>/dev/null || true
wait "$server" || status=1
pids=()

warm=$(( secs / 5 > 30 ? secs / 5 : 30 ))
awk -F, -v warm="$warm" 'NR > 1 && $1 >= warm && $2 > 0 && $3 > 0 && $4 > 0 {
    if (!n++) { s0 = $2; r0 = $3; t0 = $4 }
    s1 = $2; r1 = $3; t1 = $4; if ($2 > smax) smax = $2; if ($3 > rmax) rmax = $3; if ($4 > tmax) tmax = $4 }
  END {
    if (n < 2) { print "soak: too few memory samples after warm-up"; exit 1 }
    ds = 100 * (smax - s0) / s0; dr = 100 * (rmax - r0) / r0; dt = 100 * (tmax - t0) / t0
    printf "memory after warm-up (%d s), first -> largest: server %d -> %d kB (%+.2f %%), renderer %d -> %d kB (%+.2f %%), tool %d -> %d kB (%+.2f %%)\n", warm, s0, smax, ds, r0, rmax, dr, t0, tmax, dt
    if (ds > 1 || dr > 1 || dt > 1) { print "soak: memory grew by more than 1 % after warm-up"; exit 1 } }' "$out/rss.csv" ||
  # Under ASan, freed memory waits in its quarantine (up to 256 MB) and the shadow grows with it:
  # growth is reported, not judged; LeakSanitizer's report is the check there.
  [ "${LSAN:-0}" = 1 ] || status=1
grep -h "missed deadlines" "$out/serve.log" | tail -1 | sed 's/^.*info\] /server:   /'
grep -h "round trip" "$out/tool.log" | tail -1 | sed 's/^/tool:     /'
grep -h "frames written" "$out/render.log" | tail -1 | sed 's/^.*info\] /renderer: /'
if [ "${LSAN:-0}" = 1 ]; then
  for f in serve render tool; do
    if grep -q "LeakSanitizer" "$out/$f.log"; then echo "soak: leaks in $f:"; grep -A5 "LeakSanitizer" "$out/$f.log"; status=1; fi
  done
fi
[ "$status" -eq 0 ] && echo "soak: ok (${minutes} min; $out/rss.csv)" || echo "soak: FAILED (logs in $out/)"
exit "$status"
