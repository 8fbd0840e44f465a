#!/usr/bin/env bash
# Runs every libFuzzer target (tests/fuzz/) for SECONDS each (default 30), two at a time (the
# machine's two cores), on its seed corpus tests/fuzz/corpus/TARGET plus what it finds in this
# run (kept in build-asan/fuzz-work/, never written back to the repository). Fails on any crash,
# sanitizer report (ASan, UBSan), leak, hang (> 10 s on one input) or out-of-memory (> 2 GB):
# the input that did it is saved as build-asan/fuzz-artifacts/TARGET-* and the command that
# reproduces it is printed.
# Usage: scripts/fuzz.sh [SECONDS] [TARGET ...]      (after: cmake --preset asan && cmake --build build-asan)
set -euo pipefail
cd "$(dirname "$0")/.."
if [ "${1:-}" = "-h" ] || [ "${1:-}" = "--help" ]; then
  sed -n '2,8p' "$0" | sed 's/^# \{0,1\}//'
  exit 0
fi
secs=${1:-30}
shift || true
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(tet_mesh surface trajectory session_log state_csv scenario sofa_scene state_bytes label_image)
build=${FUZZ_BUILD:-build-asan}
work="$build/fuzz-work"
artifacts="$build/fuzz-artifacts"
mkdir -p "$artifacts"
for t in "${targets[@]}"; do
  [ -x "$build/tests/fuzz/fuzz_$t" ] || { echo "fuzz: $build/tests/fuzz/fuzz_$t is not built (cmake --preset asan && cmake --build $build)"; exit 2; }
done

run_one() {
  local t=$1
  local dict=()
  [ -f "tests/fuzz/$t.dict" ] && dict=(-dict="tests/fuzz/$t.dict")
  mkdir -p "$work/$t"
  # ASan's leak check runs at exit; UBSan reports are fatal (-fno-sanitize-recover in the build).
  if "$build/tests/fuzz/fuzz_$t" "${dict[@]}" -max_total_time="$secs" -timeout=10 -rss_limit_mb=2048 \
      -artifact_prefix="$artifacts/$t-" -print_final_stats=1 "$work/$t" "tests/fuzz/corpus/$t" \
      > "$work/$t.log" 2>&1; then
    echo "fuzz: $t ok ($(grep -o 'stat::number_of_executed_units: *[0-9]*' "$work/$t.log" | grep -o '[0-9]*$') inputs in ${secs} s)"
  else
    echo "fuzz: $t FAILED — the report:"
    # The report from its first line (a sanitizer's ERROR, UBSan's "runtime error", an uncaught
    # exception's "terminate called") with the stack, so a CI log alone says where it crashed.
    awk '/ERROR|runtime error|terminate called|what\(\)/ { on = 1 } on && n < 60 { print; n++ }' "$work/$t.log"
    grep -E "Test unit written" "$work/$t.log" | head -2
    # The input itself (base64, when small), so a crash found on another machine reproduces here.
    for a in "$artifacts/$t-"*; do
      [ -f "$a" ] && [ "$(stat -c %s "$a")" -le 16384 ] && { echo "fuzz: $(basename "$a") (base64):"; base64 -w 120 "$a"; }
    done
    echo "fuzz: reproduce with $build/tests/fuzz/fuzz_$t $artifacts/$t-<file>   (full log: $work/$t.log)"
    return 1
  fi
}

status=0
pids=()
names=()
for t in "${targets[@]}"; do
  run_one "$t" & pids+=($!); names+=("$t")
  if [ ${#pids[@]} -ge 2 ]; then
    wait "${pids[0]}" || status=1
    pids=("${pids[@]:1}")
  fi
done
for p in "${pids[@]}"; do wait "$p" || status=1; done
exit $status
