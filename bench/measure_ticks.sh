#!/usr/bin/env bash
# Tick-time table of docs/PERFORMANCE.md: median over runs of per-run p50/p99, CG iterations,
# stage split. Usage: bench/measure_ticks.sh [RUNS] [STEPS]   (after scripts/build.sh)
set -euo pipefail
cd "$(dirname "$0")/.."
runs="${1:-10}"
steps="${2:-1000}"
b=build/bench/stroma_bench_ticks
# One BLAS thread: CHOLMOD's small solves inside a 1 kHz tick gain nothing from a thread pool.
export OPENBLAS_NUM_THREADS=1
echo "| scenario | nodes | tets | tick p50 ms (run range) | tick p99 ms (run range) | max ms | CG iters mean / max | assemble / solve ms |"
echo "|---|---|---|---|---|---|---|---|"
for pc in jacobi warped_cholesky; do
  $b scenarios/liver.yaml --runs "$runs" --steps "$steps" --preconditioner $pc --markdown --label "liver, CG 1e-6, $pc"
done
for pc in jacobi warped_cholesky; do
  $b scenarios/armadillo.yaml --runs "$runs" --steps "$steps" --preconditioner $pc --markdown --label "Armadillo, CG 1e-5, $pc"
done
for h in 5p000 3p333 2p500; do
  for pc in jacobi warped_cholesky; do
    $b scenarios/cantilever_dynamic.yaml --mesh scenarios/meshes/beam_tet4_h${h}mm.msh --runs "$runs" \
       --steps "$steps" --tolerance 1e-6 --preconditioner $pc --markdown --label "cantilever h ${h/p/.} mm, CG 1e-6, $pc"
  done
done
