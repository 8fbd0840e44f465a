#!/usr/bin/env bash
# Rendering table of docs/PERFORMANCE.md: frames per second of the off-screen renderer (draw +
# read-back, the surface deforming every frame) for the liver's visual mesh and the raptor's
# surface at 640x480 and 1280x720, with and without 4x MSAA, on one rasteriser thread
# (LP_NUM_THREADS=1: "one core") and on llvmpipe's default; PNG encoding at level 1.
# Median over RUNS runs of each run's p50/p99. Usage: bench/render_fps.sh [RUNS] [FRAMES]
set -euo pipefail
cd "$(dirname "$0")/.."
runs="${1:-5}"
frames="${2:-100}"
b=build/bench/stroma_bench_render
echo "| surface | vertices | triangles | size | MSAA | llvmpipe threads | frame ms p50 (run range) | p99 (run range) | FPS (p50) | PNG level 1 ms |"
echo "|---|---|---|---|---|---|---|---|---|---|"
for mesh in "liver visual:scenarios/meshes/liver-smooth.obj" "raptor 19409 surface:scenarios/meshes/raptorTetra_19409.vtu"; do
  label="${mesh%%:*}"; path="${mesh#*:}"
  for size in 640x480 1280x720; do
    for msaa in 4 0; do
      for threads in 1 default; do
        if [ "$threads" = default ]; then run=(env -u LP_NUM_THREADS); else run=(env LP_NUM_THREADS=1); fi
        "${run[@]}" $b "$path" --width "${size%x*}" --height "${size#*x}" --msaa $msaa \
          --runs "$runs" --frames "$frames" --markdown --label "$label"
      done
    done
  done
done
