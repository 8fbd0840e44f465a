#!/usr/bin/env bash
# End-to-end recording figures of docs/PERFORMANCE.md: the demo (server at 1 kHz with FIFO,
# renderer at 30 FPS 640x480 with 4x MSAA, scripted tool at 1 kHz, all on this machine) run RUNS
# times; per run: frames written and dropped, render time, and the latency from a state's
# publication (server clock, CLOCK_MONOTONIC) to its frame being complete on disk. Prints the
# median over runs and every run. Usage: bench/render_e2e.sh [RUNS]   (after scripts/build.sh)
set -euo pipefail
cd "$(dirname "$0")/.."
runs="${1:-5}"
for i in $(seq 1 "$runs"); do
  OUT="out/bench_e2e/run$i" STROMA_DOMAIN=$((60 + i)) scripts/demo.sh > /dev/null
done
python3 - "$runs" <<'PY'
import json, statistics, sys
runs = int(sys.argv[1])
rows = []
for i in range(1, runs + 1):
    s = json.load(open(f"out/bench_e2e/run{i}/render_stats.json"))
    v = json.load(open(f"out/bench_e2e/run{i}/serve_stats.json"))
    rows.append((s["frames_written"], s["frames_dropped_late"] + s["frames_dropped_writer"], s["fps_achieved"],
                 s["render_ms"]["p50"], s["render_ms"]["p99"], s["publish_to_disk_ms"]["p50"],
                 s["publish_to_disk_ms"]["p99"], 100 * v["missed_ratio"]))
names = ["frames", "dropped", "FPS", "render p50 ms", "render p99 ms", "publish→disk p50 ms",
         "publish→disk p99 ms", "server missed %"]
print("| run | " + " | ".join(names) + " |")
print("|---" * (len(names) + 1) + "|")
for i, r in enumerate(rows, 1):
    print(f"| {i} | " + " | ".join(f"{x:.3g}" if isinstance(x, float) else str(x) for x in r) + " |")
med = [statistics.median(c) for c in zip(*rows)]
print("| **median** | " + " | ".join(f"{x:.3g}" for x in med) + " |")
PY
