#!/usr/bin/env bash
# Installs what is missing, builds, and runs the whole test suite (unit, physics, regression,
# command-line, server and interop tests) with ctest, the headless build (no DDS, no OSMesa)
# with its tests, and the lock-free hand-offs, the physics loop's threads and the preconditioner's
# refresh worker under ThreadSanitizer. This is exactly what CI runs (.ci/run).
set -euo pipefail
cd "$(dirname "$0")/.."
# Loopback only: every DDS participant started here uses Stroma's built-in loopback config,
# never an inherited CYCLONEDDS_URI that could point at another interface or multicast.
unset CYCLONEDDS_URI
scripts/setup.sh
scripts/build.sh
jobs=$(nproc 2>/dev/null || echo 2)
# Headless stage: the engine, `stroma run`, `check` and `bench` and their tests built without
# Cyclone DDS and OSMesa (CMake preset "headless": the find_package calls are disabled, so a
# dependency that crept back in fails here).
cmake --preset headless >/dev/null
cmake --build build-headless -j "$jobs"
ctest --test-dir build-headless --output-on-failure -j "$jobs"
# ThreadSanitizer stage, so ctest's summary of the full build is the last thing printed.
cmake --preset tsan >/dev/null
cmake --build build-tsan -j "$jobs" --target stroma_tests
build-tsan/tests/stroma_tests --gtest_filter='TripleBuffer*:SpscQueue*:PhysicsLoop*:CholeskyRefresher*:PreconditionerRefresh.SameTrajectory*:-PhysicsLoop.PhaseLock*' --gtest_brief=1
ctest --test-dir build --output-on-failure -j "$jobs"
