#!/usr/bin/env bash
# Installs what is missing, builds, and runs the whole test suite (unit, physics, regression,
# command-line, server and interop tests) with ctest; the headless build (no DDS, no OSMesa) with
# its tests under ASan + UBSan and the fuzz targets; and the lock-free hand-offs, the physics
# loop's threads and the preconditioner's refresh worker under ThreadSanitizer. This is exactly
# what CI runs (.ci/run). Also a 1-minute soak of the demo's three processes.
set -euo pipefail
cd "$(dirname "$0")/.."
# Loopback only: every DDS participant started here uses Stroma's built-in loopback config,
# never an inherited CYCLONEDDS_URI that could point at another interface or multicast.
unset CYCLONEDDS_URI
# Each stage's start and the seconds since the start, so a CI log shows where the time goes.
stage() { echo "=== stage: $* (at ${SECONDS} s, $(date -u +%H:%M:%S))"; }
stage setup
scripts/setup.sh
stage release build
# Everything but the benchmark programs (bench/: no test runs them; scripts/run.sh and
# scripts/build.sh build them): 90 s of the 30-minute budget.
scripts/build.sh -DSTROMA_BUILD_BENCH=OFF
jobs=$(nproc 2>/dev/null || echo 2)
# Sanitizer stage: the headless engine — `stroma run`, `check` and `bench` and their tests,
# built without Cyclone DDS and OSMesa, so a dependency that crept back in fails here — built by
# clang with AddressSanitizer and UndefinedBehaviorSanitizer (every report fatal, leaks
# included), then every libFuzzer target for a bounded time (tests/fuzz/README.md). Long physics
# runs and timing tests say so where they are defined and are left out here (tests/test_labels.hpp:
# gtest cases skip themselves in sanitizer builds; other tests carry the ctest label `long`); the
# release suite runs them all.
stage sanitizer build
cmake --preset asan >/dev/null
cmake --build build-asan -j "$jobs"
stage sanitizer tests
ctest --test-dir build-asan --output-on-failure -j "$jobs" -LE long
stage fuzzing
scripts/fuzz.sh "${STROMA_FUZZ_SECONDS:-6}"
# A 1-minute soak of the demo's three processes (server, renderer, looping tool client):
# memory flat after warm-up, nothing dies (bench/soak.sh; the 60-minute figures: REALTIME.md).
stage soak
bench/soak.sh 1
# ThreadSanitizer stage, so ctest's summary of the full build is the last thing printed.
stage thread sanitizer
cmake --preset tsan >/dev/null
cmake --build build-tsan -j "$jobs" --target stroma_thread_tests
build-tsan/tests/stroma_thread_tests --gtest_filter='TripleBuffer*:SpscQueue*:PhysicsLoop*:CholeskyRefresher*:PreconditionerRefresh.SameTrajectory*:Multirate.TheServedWorker*' --gtest_brief=1
stage release tests
ctest --test-dir build --output-on-failure -j "$jobs"
