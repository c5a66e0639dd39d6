#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# The collision check's cost (issue 38: at most as much again as translation): each bundled
# example with bodies, and the corpus's deformed tet (Cura, planar) on rw2 and pentarod when
# CORPUS_DIR (default ../shared/corpus) has it, translated with --collision off and --collision
# warn, the machine being
# machines/NAME.toml with tests/bodies/NAME.toml appended (no bundled machine has bodies yet:
# bench/README.md says why).
# Prints the best of 3 wall times of the whole file, instructions per line (callgrind, as
# instructions.sh: (count for the first LINES lines - count for the first 5) / (LINES - 5)), the
# same over the whole file, each with the ratio warn / off, and the number of collisions warn
# reports on the whole file (false alarms: the examples print as written).
#
#   bench/collision.sh [BUILD_DIR=build] [LINES=300]
set -euo pipefail
build=${1:-build}
lines=${2:-300}
here=$(cd "$(dirname "$0")/.." && pwd)
command -v valgrind >/dev/null || { echo "collision.sh: valgrind is not installed (apt install valgrind)"; exit 2; }
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
x=$build/cli/xlate5
collected() {  # collected MACHINE FILE MODE
    valgrind --tool=callgrind --callgrind-out-file="$dir/cg.out" "$x" -m "$1" -i "$2" -o /dev/null --collision "$3" 2>&1 |
        sed -n 's/.*Collected : \([0-9]*\).*/\1/p'
}
best_time() {  # best_time MACHINE FILE MODE: least of 3 wall times, s
    for _ in 1 2 3; do
        /usr/bin/time -f %e "$x" -m "$1" -i "$2" -o /dev/null --collision "$3" 2>&1 >/dev/null | tail -1
    done | sort -n | head -1
}
printf '%-18s %6s %6s %10s %10s %6s %10s %10s %6s %10s\n' file "off s" "warn s" "off ins/ln" "warn ins/ln" ratio \
    "whole off" "whole warn" ratio collisions
corpus=${CORPUS_DIR:-$here/../shared/corpus}
tet=$corpus/planar/pi_3mm_deformed_tet_cura-5.8.0.gcode
pairs="rw2:$here/examples/rw2_flared_wall.gcode pentarod:$here/examples/pentarod_dome.gcode"
# A real slicer's planar file (Cura, from the corpus) on a head-head and a table-table machine.
[ -f "$tet" ] && pairs="$pairs rw2:$tet pentarod:$tet"
for pair in $pairs; do
    m=${pair%%:*} f=${pair#*:}
    cat "$here/machines/$m.toml" "$here/tests/bodies/$m.toml" >"$dir/$m.toml"
    head -"$lines" "$f" >"$dir/part.gcode"
    head -5 "$f" >"$dir/head.gcode"
    per() {  # per FILE LINES MODE: instructions a line over lines 6..LINES
        awk -v w="$(collected "$dir/$m.toml" "$1" "$3")" -v h="$(collected "$dir/$m.toml" "$dir/head.gcode" "$3")" \
            -v n="$2" 'BEGIN { printf "%.0f", (w - h) / (n - 5) }'
    }
    n=$(wc -l <"$f")
    po=$(per "$dir/part.gcode" "$lines" off) pw=$(per "$dir/part.gcode" "$lines" warn)
    wo=$(per "$f" "$n" off) ww=$(per "$f" "$n" warn)
    found=$("$x" -m "$dir/$m.toml" -i "$f" -o /dev/null --collision warn 2>&1 | grep -c "warning: collision" || true)
    printf '%-18s %6s %6s %10s %10s %6.2f %10s %10s %6.2f %10s\n' "$m/$(basename "$f" .gcode | cut -c1-$((17 - ${#m})))" "$(best_time "$dir/$m.toml" "$f" off)" \
        "$(best_time "$dir/$m.toml" "$f" warn)" "$po" "$pw" "$(echo "$pw / $po" | bc -l)" "$wo" "$ww" "$(echo "$ww / $wo" | bc -l)" "$found"
done
