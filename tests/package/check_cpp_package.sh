#!/usr/bin/env bash
# The engine as an installed CMake package (issue 18 §4; docs/EMBEDDING.md), as a user gets it:
# `cmake --install` into a fresh prefix, examples/embed configured against it with
# find_package(stroma) (nothing from the source or build tree on its include or link paths),
# built, and run on a regression scenario. Asserted: its final state is the same bits as
# `stroma run`'s and passes `stroma check` (the installed CLI); a bad scenario exits 2 with the
# engine's message; find_package(stroma 9) is refused (the version file).
# Usage: check_cpp_package.sh SOURCE_DIR BUILD_DIR
set -euo pipefail
src=$1 build=$2
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

cmake --install "$build" --prefix "$tmp/prefix" >/dev/null
[[ -f $tmp/prefix/lib/cmake/stroma/stromaConfig.cmake ]] || fail "no stromaConfig.cmake installed"
[[ -f $tmp/prefix/include/stroma/engine/tick.hpp ]] || fail "headers not installed"

gen=(); command -v ninja >/dev/null && gen=(-G Ninja)
cmake -S "$src/examples/embed" -B "$tmp/embed" "${gen[@]}" -DCMAKE_PREFIX_PATH="$tmp/prefix" >/dev/null
cmake --build "$tmp/embed" >/dev/null
# The consumer was compiled against the installed headers, not the source tree's.
grep -q -- "-I$src\b\|-isystem $src\b" "$tmp/embed/build.ninja" 2>/dev/null && fail "the consumer saw the source tree"
grep -q "$tmp/prefix/include" "$tmp/embed/build.ninja" 2>/dev/null || [[ ${#gen[@]} -eq 0 ]] || fail "installed include dir not used"

scenario=$src/scenarios/regression/liver_probe_press.yaml
"$tmp/embed/embed_stroma" "$scenario" --state "$tmp/embedded.csv" > "$tmp/out.txt"
grep -q "probe lobe: displacement" "$tmp/out.txt" || fail "no probe reading: $(cat "$tmp/out.txt")"
"$tmp/prefix/bin/stroma" run "$scenario" --out "$tmp/run" --quiet --no-metrics >/dev/null 2>&1
cmp -s "$tmp/run/final_state.csv" "$tmp/embedded.csv" || fail "the embedded engine's final state differs from stroma run's"
"$tmp/prefix/bin/stroma" check "$scenario" "$tmp/embedded.csv" >/dev/null 2>&1 || fail "stroma check rejects the embedded run"
# A moved scenario exercises the error path (exit 2, the engine's file: message).
set +e
"$tmp/embed/embed_stroma" "$tmp/missing.yaml" 2> "$tmp/err.txt"; rc=$?
set -e
[[ $rc -eq 2 ]] || fail "a missing scenario exited $rc, not 2"
grep -q "missing.yaml" "$tmp/err.txt" || fail "the error does not name the file: $(cat "$tmp/err.txt")"
# The version file refuses an incompatible request.
mkdir -p "$tmp/v9"
printf 'cmake_minimum_required(VERSION 3.25)\nproject(v9 LANGUAGES CXX)\nfind_package(stroma 9 REQUIRED)\n' > "$tmp/v9/CMakeLists.txt"
if cmake -S "$tmp/v9" -B "$tmp/v9/b" -DCMAKE_PREFIX_PATH="$tmp/prefix" >/dev/null 2>&1; then
  fail "find_package(stroma 9) was accepted"
fi
echo "cmake --install -> find_package(stroma) -> embed_stroma: ok ($(head -1 "$tmp/out.txt"))"
