#!/usr/bin/env bash
# Tick-time table of docs/PERFORMANCE.md: median over runs of per-run p50/p99, CG iterations,
# stage split. Usage: bench/measure_ticks.sh [RUNS] [STEPS]   (after scripts/build.sh)
set -euo pipefail
cd "$(dirname "$0")/.."
runs="${1:-10}"
steps="${2:-1000}"
b=build/bench/stroma_bench_ticks
echo "| scenario | nodes | tets | tick p50 ms (run range) | tick p99 ms (run range) | max ms | CG iters mean / max | assemble / solve ms |"
echo "|---|---|---|---|---|---|---|---|"
$b scenarios/liver.yaml --runs "$runs" --steps "$steps" --markdown --label "liver (SOFA demo, dt 1 ms, CG 1e-6)"
$b scenarios/armadillo.yaml --runs "$runs" --steps "$steps" --markdown --label "Armadillo (E 3 kPa, nu 0.45, CG 1e-5)"
for h in 5p000 3p333 2p500; do
  $b scenarios/cantilever_dynamic.yaml --mesh scenarios/meshes/beam_tet4_h${h}mm.msh --runs "$runs" \
     --steps "$steps" --markdown --label "cantilever h=${h/p/.} mm (CG 1e-8)"
  $b scenarios/cantilever_dynamic.yaml --mesh scenarios/meshes/beam_tet4_h${h}mm.msh --runs "$runs" \
     --steps "$steps" --tolerance 1e-6 --markdown --label "cantilever h=${h/p/.} mm (CG 1e-6)"
done
