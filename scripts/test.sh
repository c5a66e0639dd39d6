#!/usr/bin/env bash
# Installs the dependencies, builds xlate5 and runs the whole test suite: once in a release
# build, once under AddressSanitizer + UndefinedBehaviorSanitizer. Small benchmark runs in
# between print their figures (no timing is asserted), so a slowdown shows in every CI log.
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/install-deps.sh
jobs=$(nproc 2>/dev/null || echo 2)
# Most of the suite's time is spent waiting on pseudo-terminals and timers (the fault tests),
# not on the processors, so one test program more than the cores runs at once.
test_jobs=$((jobs + 1))

cmake -S . -B build -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build build -j"$jobs"
ctest --test-dir build --output-on-failure -j"$test_jobs"

echo "--- benchmarks (figures only; see bench/)"
./build/bench/bench_translate 100000 rw2 0.01
./build/bench/bench_translate 100000 pentarod 0.01
./build/bench/bench_translate 100000 rw2 0
./build/bench/bench_service 5000 0

# Every fuzz target for 15 s on its seeds (clang; only the fuzz targets are built; fuzz/README.md).
echo "--- fuzz targets, 15 s each"
./scripts/fuzz.sh 15

# -O1 without debug info: the sanitizer build is about finding bugs, and compiles much faster.
# The packaging tests (manual page, completion, .deb) check files, not memory: release only.
cmake -S . -B build-asan -DCMAKE_BUILD_TYPE=None -DCMAKE_CXX_FLAGS="-O1" -DXLATE5_SANITIZE=ON -DXLATE5_BENCH=OFF >/dev/null
cmake --build build-asan -j"$jobs"
ASAN_OPTIONS=detect_leaks=1 UBSAN_OPTIONS=print_stacktrace=1 \
  ctest --test-dir build-asan --output-on-failure -j"$test_jobs" -E '^(man_page|bash_completion|debian_package)$'
