#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# Instructions per input line of the offline translator, counted by valgrind's callgrind: exact
# and the same on every run of the same build, whatever else the machine is doing, where the
# benchmark's times move by up to twice on a shared machine. Program start is left out: each
# figure is (count for the whole file - count for its first 5 lines, the header) / lines.
#
#   bench/instructions.sh [BUILD_DIR=build] [LINES=20000]
#
# Runs xlate5 from BUILD_DIR on bench_translate's own generated files: rw2 without splitting,
# rw2 at 0.01 mm, pentarod at 0.01 mm (the benchmark's three figures), then bench_floor on the
# same rw2 file (the lexer, the position solve and the number writer alone): a yardstick that
# moves with the code, not with the machine, where a time's ratio to the floor moves with both.
set -euo pipefail
build=${1:-build}
lines=${2:-20000}
command -v valgrind >/dev/null || { echo "instructions.sh: valgrind is not installed (apt install valgrind)"; exit 2; }
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
collected() {  # collected COMMAND...: instructions of one whole run
    valgrind --tool=callgrind --callgrind-out-file="$dir/cg.out" "$@" 2>&1 | sed -n 's/.*Collected : \([0-9]*\).*/\1/p'
}
count() {  # count MACHINE FILE ARGS...: instructions of one whole run of xlate5
    local m=$1 f=$2
    shift 2
    collected "$build/cli/xlate5" -m "$m" -i "$f" "$@" -o /dev/null
}
per_line() {  # per_line LABEL WHOLE HEAD
    awk -v w="$2" -v h="$3" -v n="$lines" -v r="$1" 'BEGIN { printf "%-28s %7.0f instructions a line (%d lines)\n", r, (w - h) / n, n }'
}
for m in rw2 pentarod; do
    "$build/bench/bench_translate" "$lines" "$m" 0 "$dir/$m.gcode" >/dev/null
    head -5 "$dir/$m.gcode" >"$dir/$m-head.gcode"
done
for run in "rw2 --no-segment" "rw2 --tolerance=0.01" "pentarod --tolerance=0.01"; do
    read -r m opt <<<"$run"
    whole=$(count "$m" "$dir/$m.gcode" "$opt")
    head=$(count "$m" "$dir/$m-head.gcode" "$opt")
    per_line "$m $opt" "$whole" "$head"
done
if [ -x "$build/bench/bench_floor" ]; then
    per_line "floor (bench_floor, rw2)" "$(collected "$build/bench/bench_floor" "$dir/rw2.gcode" rw2)" \
        "$(collected "$build/bench/bench_floor" "$dir/rw2-head.gcode" rw2)"
fi
