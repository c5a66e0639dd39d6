#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# Builds the fuzz targets (fuzz/, clang + libFuzzer + ASan + UBSan) in build-fuzz/ and runs each
# for SECONDS (default 60) on seeds derived from the examples, the machine files and, when
# present, ../shared/corpus. Inputs the fuzzers add are kept in build-fuzz/fuzz-corpus/<target>,
# crashes in build-fuzz/fuzz-artifacts/. Exit status 1 if any target found a crash.
# Longer runs: fuzz/README.md.
# `fuzz.sh --build-only` builds the targets and their seeds and runs nothing.
# XLATE5_FUZZ_BUILD names another build tree configured with -DXLATE5_FUZZ=ON (scripts/test.sh
# builds the sanitizer tests and the fuzz targets in one tree, so the libraries compile once).
set -euo pipefail
seconds="${1:-60}"
root="$(cd "$(dirname "$0")/.." && pwd)"
build="${XLATE5_FUZZ_BUILD:-$root/build-fuzz}"
"$root/scripts/install-deps.sh" fuzz
if [ ! -f "$build/CMakeCache.txt" ]; then
  CC=clang CXX=clang++ cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DXLATE5_FUZZ=ON -DXLATE5_TESTS=OFF -DXLATE5_BENCH=OFF
fi
cmake --build "$build" -j2 --target fuzz
"$root/fuzz/make_seeds.sh" "$build/fuzz-seeds"
[ "$seconds" = --build-only ] && exit 0
mkdir -p "$build/fuzz-artifacts"
status=0
# The translate target's inputs are kept short: a move is costly (it is split into pieces), and
# short inputs reach the same code more often.
declare -A max_len=([fuzz_translate]=512 [fuzz_machine_file]=8192 [fuzz_compensation]=4096 [fuzz_calibrate]=2048
                     [fuzz_sender_line]=4096 [fuzz_firmware_reply]=2048 [fuzz_protocol]=4096)
for t in fuzz_translate fuzz_machine_file fuzz_compensation fuzz_calibrate fuzz_sender_line fuzz_firmware_reply fuzz_protocol; do
  mkdir -p "$build/fuzz-corpus/$t"
  log="$build/fuzz-artifacts/$t.log"
  echo "== $t, ${seconds} s"
  if "$build/fuzz/$t" -max_total_time="$seconds" -max_len="${max_len[$t]}" -timeout=10 -rss_limit_mb=2048 \
       -print_final_stats=1 -artifact_prefix="$build/fuzz-artifacts/$t-" \
       "$build/fuzz-corpus/$t" "$build/fuzz-seeds/$t" > "$log" 2>&1; then
    grep -E '^#[0-9]+.*(DONE|pulse)' "$log" | tail -1 || true
    grep -E '^stat::(number_of_executed_units|average_exec_per_sec)' "$log" || true
  else
    status=1
    echo "$t: FAILED, see $log"; grep -E 'ERROR|SUMMARY|Test unit written' "$log" || tail -20 "$log"
  fi
done
exit $status
