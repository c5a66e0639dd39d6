#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# Offline output of two xlate5 builds, compared byte for byte: every corpus file and bundled
# example on every bundled machine, in each start mode, split and unsplit, with --report, the
# S3-DeformFDM extrusion letter, the rw2 compensation file, and --inverse (both preview forms) of
# every output plus the translation of that preview back. Output, standard error, exit code and
# report must all match.
#
#   scripts/compare-outputs.sh BINARY_A BINARY_B [CORPUS_DIR]
#
# BINARY_A may instead be a directory written by an earlier run (kept as out-A), so a baseline
# is run once; BINARY_B "none" only writes out-A. Outputs go to $COMPARE_DIR (default: ./compare-out);
# B's to $COMPARE_OUT_B if set (so that several builds can be held against one baseline at once:
# messages name the generated inputs under $COMPARE_DIR, which must then be the same). Exit 0 when all match.
set -uo pipefail
cd "$(dirname "$0")/.."
A=$1
B=$2
CORPUS=${3:-../shared/corpus}
DIR=${COMPARE_DIR:-compare-out}
mkdir -p "$DIR"

# Two inputs written here for what the files above barely reach: the joint-limit look-back (rw2's
# A, +-168 degrees, passed while printing round a loop with a layer change half way; without it:
# the error) and arcs (planes, I J K and R, helical, P turns, inches, absolute and relative E).
gen=$DIR/inputs
mkdir -p "$gen"
python3 - "$gen" <<'PY'
import math, sys
d = sys.argv[1]
def loop(travel):
    out = ["M83"]
    a, z = 0.0, 5.0
    def tip(a, z): return (110 + 20 * math.cos(math.radians(-a)), 110 + 20 * math.sin(math.radians(-a)), z)
    def mv(g, a, z, e, first=False):
        x, y, zz = tip(a, z)
        out.append(f"{g} X{x:.6f} Y{y:.6f} Z{zz:.6f} A{a:.3f} B30" + (" E0.05" if e else "") + (" F1200" if first else ""))
    mv("G0", a, z, False, True)
    while a < 300 - 1e-9:
        if travel and abs(a - 150) < 1e-9:
            mv("G0", a, z + 0.3, False); z += 0.3
        a = min(a + 5, 300)
        mv("G1", a, z, True)
    return "\n".join(out) + "\n"
open(f"{d}/lookback_azimuth.gcode", "w").write(loop(True))
open(f"{d}/lookback_no_travel.gcode", "w").write(loop(False))
open(f"{d}/arcs.gcode", "w").write("""G21
G90
M82
G0 X40 Y40 Z10 F3000
G1 X50 Y40 Z10 E1 F1200
G2 X60 Y50 I0 J10 E2
G3 X50 Y60 R10 E3
G2 X50 Y60 I0 J-10 Z12 P2 E4
G18
G2 X60 Z10 I5 K-1 E5
G19
G3 Y50 Z12 R-8 E6
G17
M83
G91
G2 X5 Y5 I5 J0 E0.5
G90
G1 X50.8 Y50.8
G20
G3 X2.2 Y2 I0.1 J0 E0.1
G21
G1 X50 Y50 A10 B20 E0.2
G2 X60 Y50 R5 A20 E0.3
G2 X70 Y50 R5 A30 F600
""")
PY

files=()
for f in "$CORPUS"/*/*; do [[ -f $f ]] && files+=("$f"); done
for f in "$gen"/*.gcode; do files+=("$f"); done
for f in examples/*.gcode; do files+=("$f"); done
machines=()
for m in machines/*.toml; do machines+=("$(basename "$m" .toml)"); done

# run BIN OUTDIR NAME ARGS...: one translation, its output, stderr, exit code (and report).
run() {
    local bin=$1 out=$2 name=$3
    shift 3
    "$bin" "$@" -o "$out/$name.out" 2>"$out/$name.err"
    echo $? >"$out/$name.rc"
}

run_all() {
    local bin=$1 out=$2
    rm -rf "$out"
    mkdir -p "$out"
    for f in "${files[@]}"; do
        local base
        base=$(basename "$f")
        for m in "${machines[@]}"; do
            local variants=("default::" "g49::--mode G49" "g435::--mode G43.5" "noseg::--no-segment")
            [[ $base == ring_Gcode.txt ]] && variants+=("extA::--extruder-letter A" "extAg49::--extruder-letter A --mode G49")
            [[ $m == rw2 ]] && variants+=("comp::--compensation machines/compensation/rw2-seed001.toml")
            for v in "${variants[@]}"; do
                local tag=${v%%::*} args=${v#*::}
                local name="$base.$m.$tag"
                # shellcheck disable=SC2086
                run "$bin" "$out" "$name" --machine "$m" -i "$f" --report "$out/$name.json" $args
                [[ $(cat "$out/$name.rc") == 0 ]] || continue
                [[ $tag == default || $tag == comp || $tag == g49 ]] || continue
                local extra=()
                [[ $tag == comp ]] && extra=(--compensation machines/compensation/rw2-seed001.toml)
                run "$bin" "$out" "$name.inv" --machine "$m" "${extra[@]}" --inverse -i "$out/$name.out" --report "$out/$name.inv.json"
                run "$bin" "$out" "$name.inv5" --machine "$m" "${extra[@]}" --inverse --preview-form G43.5 -i "$out/$name.out"
                # The preview translated back (round trip).
                [[ $(cat "$out/$name.inv.rc") == 0 ]] && run "$bin" "$out" "$name.inv.fwd" --machine "$m" "${extra[@]}" -i "$out/$name.inv.out"
                [[ $(cat "$out/$name.inv5.rc") == 0 ]] && run "$bin" "$out" "$name.inv5.fwd" --machine "$m" "${extra[@]}" --mode G43.5 -i "$out/$name.inv5.out"
            done
        done
    done
}

if [[ -d $A ]]; then
    outA=$A
else
    outA=$DIR/out-A
    run_all "$(realpath "$A")" "$outA"
fi
# A binary that found no machines (a copy away from its share/ directory) fails every run: two
# such builds would "match". Refuse a baseline that translated nothing.
grep -qx 0 "$outA"/*.rc || { echo "compare-outputs: $A translated none of the inputs (does it find its machines?)"; exit 2; }
[[ $B == none ]] && { echo "outputs of $A in $outA"; exit 0; }
outB=${COMPARE_OUT_B:-$DIR/out-B}
run_all "$(realpath "$B")" "$outB"

# Input names inside reports and messages point at the run's own directory: compare with it
# replaced by a fixed word.
norm() { sed "s#$2#OUT#g" "$1"; }
differ=0
count=0
for fa in "$outA"/*; do
    name=$(basename "$fa")
    fb=$outB/$name
    count=$((count + 1))
    if [[ ! -e $fb ]]; then
        echo "missing in B: $name"
        differ=$((differ + 1))
    elif ! cmp -s "$fa" "$fb" && ! cmp -s <(norm "$fa" "$outA") <(norm "$fb" "$outB"); then
        echo "differs: $name"
        differ=$((differ + 1))
    fi
done
for fb in "$outB"/*; do
    [[ -e $outA/$(basename "$fb") ]] || { echo "missing in A: $(basename "$fb")"; differ=$((differ + 1)); }
done
echo "$count files compared, $differ differ"
[[ $differ == 0 ]]
