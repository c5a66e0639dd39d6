#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# Installs the dependencies, builds xlate5 and runs the whole test suite: once in a release
# build, once under AddressSanitizer + UndefinedBehaviorSanitizer, and each fuzz target briefly.
# Small benchmark runs in between print their figures (no timing is asserted), so a slowdown
# shows in every CI log.
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/install-deps.sh fuzz  # the build, the tests, and clang for the fuzz targets
jobs=$(nproc 2>/dev/null || echo 2)
# Most of the suite's time is spent waiting on pseudo-terminals and timers (the fault tests),
# not on the processors, so one test program more than the cores runs at once.
test_jobs=$((jobs + 1))

cmake -S . -B build -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build build -j"$jobs"

echo "--- benchmarks (figures only; see bench/)"
./build/bench/bench_translate 100000 rw2 0.01
./build/bench/bench_translate 100000 pentarod 0.01
floor_input=$(mktemp --suffix=.gcode)
./build/bench/bench_translate 100000 rw2 0 "$floor_input"  # keeps its input for the floor below
./build/bench/bench_floor "$floor_input" rw2
rm -f "$floor_input"
./build/bench/bench_service 5000 0
bench/instructions.sh build 20000  # exact counts: the steady figure where times move with the machine

ctest --test-dir build --output-on-failure -j"$test_jobs"

# The sanitizer tests and the fuzz targets in one clang tree (ASan + UBSan, libFuzzer's coverage
# on the libraries), so the libraries compile once; -O1 without debug info: the tree is about
# finding bugs, and compiles much faster. Built with clang (needed for the fuzz targets in any
# case): the same tree and flags took 286 s against g++'s 406 s on two cores.
# The packaging tests (manual page, completion, .deb) check files, not memory, and the preview
# tests spend their time in Chromium (test_cli writes the same pages under the sanitizers):
# release only (in one CI log the seven previews were 129 s of the sanitizer tests, 3 at once).
cmake -S . -B build-asan -DCMAKE_CXX_COMPILER=clang++ -DCMAKE_BUILD_TYPE=None -DCMAKE_CXX_FLAGS="-O1" \
    -DXLATE5_SANITIZE=ON -DXLATE5_FUZZ=ON -DXLATE5_BENCH=OFF >/dev/null
cmake --build build-asan -j"$jobs"
export XLATE5_FUZZ_BUILD=$PWD/build-asan
./scripts/fuzz.sh --build-only

asan_log=$(mktemp)
trap 'rm -f "$asan_log"' EXIT
# The sanitizer tests mostly wait on pseudo-terminals and timers, so each fuzz target runs 10 s
# on its seeds meanwhile; the tests' output is printed after the fuzz figures.
( ASAN_OPTIONS=detect_leaks=1 UBSAN_OPTIONS=print_stacktrace=1 \
    ctest --test-dir build-asan --output-on-failure -j"$test_jobs" -E '^(man_page|bash_completion|debian_package|e2e_preview_.*)$' \
    > "$asan_log" 2>&1 ) &
asan=$!
echo "--- fuzz targets, 10 s each"
fuzz_status=0
./scripts/fuzz.sh 10 || fuzz_status=$?
asan_status=0
wait "$asan" || asan_status=$?
echo "--- sanitizer build's tests (ASan+UBSan)"
cat "$asan_log"
if [ "$fuzz_status" -ne 0 ]; then echo "a fuzz target failed (above)"; fi
[ "$fuzz_status" -eq 0 ] && [ "$asan_status" -eq 0 ]
