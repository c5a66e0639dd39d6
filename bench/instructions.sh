#!/usr/bin/env bash
# Instructions per input line of the offline translator, counted by valgrind's callgrind: exact
# and the same on every run of the same build, whatever else the machine is doing, where the
# benchmark's times move by up to twice on a shared machine. Program start is left out: each
# figure is (count for the whole file - count for its first 5 lines, the header) / lines.
#
#   bench/instructions.sh [BUILD_DIR=build] [LINES=20000]
#
# Runs xlate5 from BUILD_DIR on bench_translate's own generated files: rw2 without splitting,
# rw2 at 0.01 mm, pentarod at 0.01 mm (the benchmark's three figures).
set -euo pipefail
build=${1:-build}
lines=${2:-20000}
command -v valgrind >/dev/null || { echo "instructions.sh: valgrind is not installed (apt install valgrind)"; exit 2; }
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
count() {  # count MACHINE FILE ARGS...: instructions of one whole run
    local m=$1 f=$2
    shift 2
    valgrind --tool=callgrind --callgrind-out-file="$dir/cg.out" "$build/cli/xlate5" -m "$m" -i "$f" "$@" -o /dev/null 2>&1 |
        sed -n 's/.*Collected : \([0-9]*\).*/\1/p'
}
for m in rw2 pentarod; do
    "$build/bench/bench_translate" "$lines" "$m" 0 "$dir/$m.gcode" >/dev/null
    head -5 "$dir/$m.gcode" >"$dir/$m-head.gcode"
done
for run in "rw2 --no-segment" "rw2 --tolerance=0.01" "pentarod --tolerance=0.01"; do
    read -r m opt <<<"$run"
    whole=$(count "$m" "$dir/$m.gcode" "$opt")
    head=$(count "$m" "$dir/$m-head.gcode" "$opt")
    awk -v w="$whole" -v h="$head" -v n="$lines" -v r="$m $opt" 'BEGIN { printf "%-28s %7.0f instructions a line (%d lines)\n", r, (w - h) / n, n }'
done
