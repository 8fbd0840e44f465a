#!/usr/bin/env bash
# Configures and builds Stroma into build/ (Release, Ninja). Usage: scripts/build.sh [cmake args]
set -euo pipefail
cd "$(dirname "$0")/.."
jobs=$(nproc 2>/dev/null || echo 2)
# The benchmark programs unless told otherwise (scripts/test.sh leaves them out): the cache
# keeps the last value, so it is set each time.
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release -DSTROMA_BUILD_BENCH=ON "$@" >/dev/null
cmake --build build -j "$jobs"
