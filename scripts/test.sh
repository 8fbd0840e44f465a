#!/usr/bin/env bash
# Installs what is missing, builds, and runs the whole test suite (unit, physics, regression,
# command-line, server and interop tests) with ctest, plus the lock-free hand-offs and the
# physics loop's threads under ThreadSanitizer. This is exactly what CI runs (.ci/run).
set -euo pipefail
cd "$(dirname "$0")/.."
# Loopback only: every DDS participant started here uses Stroma's built-in loopback config,
# never an inherited CYCLONEDDS_URI that could point at another interface or multicast.
unset CYCLONEDDS_URI
scripts/setup.sh
scripts/build.sh
jobs=$(nproc 2>/dev/null || echo 2)
# ThreadSanitizer stage first, so ctest's summary is the last thing printed.
cmake --preset tsan >/dev/null
cmake --build build-tsan -j "$jobs" --target stroma_tests
build-tsan/tests/stroma_tests --gtest_filter='TripleBuffer*:SpscQueue*:PhysicsLoop*' --gtest_brief=1
ctest --test-dir build --output-on-failure -j "$jobs"
