#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# Writes the seed corpora of the fuzz targets into DIR/<target>/ from what is at hand when run:
# the shared third-party corpus (../shared/corpus, when present; its files are never copied into
# the tree), the examples and the bundled machine files. Each seed starts with the selector bytes
# its target reads (fuzz/*.cpp), spread over the machines and modes.
# Usage: fuzz/make_seeds.sh DIR [CORPUS_DIR]
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
out="$1"
corpus="${2:-$root/../shared/corpus}"
mkdir -p "$out"/{fuzz_translate,fuzz_machine_file,fuzz_compensation,fuzz_calibrate,fuzz_sender_line,fuzz_firmware_reply,fuzz_protocol}
tmp="$(mktemp -d)"; trap 'rm -rf "$tmp"' EXIT

# fuzz_translate: G-code in pieces of about 3 KB (libFuzzer works on short inputs), at most 24
# pieces a file, each under a different machine and configuration byte.
gcode=("$root"/examples/*.gcode "$root"/examples/*_waypoints.txt)
[ -d "$corpus" ] && while IFS= read -r -d '' f; do gcode+=("$f"); done \
  < <(find "$corpus" -type f \( -name '*.gcode' -o -name '*.ngc' -o -name '*.txt' -o -name '*.cls' \) -print0)
n=0
for f in "${gcode[@]}"; do
  rm -f "$tmp"/piece.*
  head -c 400000 "$f" | split -C 3000 -a 4 - "$tmp/piece."
  k=0
  for p in "$tmp"/piece.*; do
    [ $k -ge 24 ] && break
    # CL files (.cls) as CL data, waypoint tables as such: bits 6-7 of the configuration byte 2, 3.
    cfg=$(((n / 6) % 64)); case "$f" in *.cls) cfg=$((cfg | 128));; *_waypoints.txt) cfg=$((cfg | 192));; esac
    printf "\\x$(printf %02x $((n % 6)))\\x$(printf %02x $cfg)" > "$out/fuzz_translate/seed_$n"
    cat "$p" >> "$out/fuzz_translate/seed_$n"
    n=$((n + 1)); k=$((k + 1))
  done
done

# fuzz_machine_file: the bundled machines as they are.
for f in "$root"/machines/*.toml; do cp "$f" "$out/fuzz_machine_file/$(basename "$f")"; done

# fuzz_compensation: each compensation file under each machine.
i=0
for f in "$root"/machines/compensation/*.toml; do
  for m in 0 1 2 3 4 5; do
    { printf "\\x$(printf %02x $m)"; cat "$f"; } > "$out/fuzz_compensation/seed_${i}_$m"
  done
  i=$((i + 1))
done

# fuzz_calibrate: the measured error table for fit (orders 1..3), and small tables of the other
# commands' shapes derived from it (pairs for offset and centre, triples for plate).
csv="$root/examples/rw2_table_4_2_z.csv"
for order in 0 5 10; do { printf "\\x$(printf %02x $order)\\x00"; cat "$csv"; } > "$out/fuzz_calibrate/fit_$order"; done
{ printf '\x01\x00'; grep -v '^#' "$csv" | awk -F, 'NF==2 {print $1 "," $2 "," NR*0.5}'; } > "$out/fuzz_calibrate/plate"
{ printf '\x02\x00'; grep -v '^#' "$csv" | head -8; } > "$out/fuzz_calibrate/offset"
{ printf '\x03\x00'; printf '10,0\n0,10\n-10,0\n0,-10.01\n'; } > "$out/fuzz_calibrate/centre"
for m in 0 1 2 3 4 5; do
  # pivots: rows of (joints..., tip x,y,z); the joint count differs per machine, the fuzzer finds it.
  { printf "\\x$(printf %02x $((4 + 5 * m)))\\x03"; printf '0,0,0,0,0,0,0,0\n1,2,3,0,0,1,2,3\n5,0,0,10,0,5,0,0\n0,5,0,0,10,0,5,0\n'; } \
    > "$out/fuzz_calibrate/pivots_$m"
done
# The service's inputs: a sender's numbered lines (from the examples, with M110 and a few
# damaged copies), a firmware's replies, and scripts of a greeting, a print and its faults.
/usr/bin/python3 - "$out" "$root"/examples/*.gcode <<'PY'
import os, sys
out, files = sys.argv[1], sys.argv[2:]
def cs(t):
    c = 0
    for b in t.encode(): c ^= b
    return c
def num(n, cmd):
    l = "N%d %s" % (n, cmd)
    return "%s*%d" % (l, cs(l))
for i, f in enumerate(files):
    cmds = [l.split(";")[0].strip() for l in open(f, errors="replace")]
    cmds = [c for c in cmds if c][:60]
    lines = [num(0, "M110 N0")] + [num(k + 1, c) for k, c in enumerate(cmds)]
    lines[5:5] = ["N;0" + lines[5][2:], lines[4], "M110 N9223372036854775807", "G28*12", lines[6]]
    for strict in (0, 1):
        open(os.path.join(out, "fuzz_sender_line", "seed_%d_%d" % (i, strict)), "wb").write(bytes([strict]) + ("\n".join(lines) + "\n").encode())
replies = ["start", "echo:Marlin 2.1.2", "ok", "ok N10 P15 B3", "ok T:20.0 /0.0 B:20.0 /0.0 @:0 B@:0", "Resend: 5", "rs 5",
           "echo:busy: processing", "busy: paused for user", "wait", "Error:checksum mismatch, Last Line: 4",
           "Error:Line Number is not Last Line Number+1, Last Line: 4", "Error:No Checksum with line number, Last Line: 4",
           "Error:Printer halted. kill() called!", "Error:Printer stopped due to errors. Fix the error and use M999 to restart.",
           "FIRMWARE_NAME:Marlin 2.1.2 (Github) SOURCE_CODE_URL:github.com/MarlinFirmware/Marlin PROTOCOL_VERSION:1.0 MACHINE_TYPE:3D Printer EXTRUDER_COUNT:1",
           "Cap:ADVANCED_OK:1", "X:10.00 Y:20.00 Z:5.00 E:0.00 Count X:800 Y:1600 Z:2000", "echo:Unknown command: \"G43.4\""]
open(os.path.join(out, "fuzz_firmware_reply", "replies"), "w").write("\n".join(replies) + "\n")
greet = ["rstart", "t9", "t9", "t9", "rok", "r" + replies[15], "rCap:ADVANCED_OK:1", "rok", "t9", "t9", "t9"]
moves = ["eG1 X%d Y%d A%d B%d" % (k, 2 * k, k % 90, k % 30) for k in range(12)]
scripts = {
    "clean": greet + sum([[m, "rok"] for m in moves], []),
    "advanced": greet + moves[:6] + ["rok N1 P15 B3", "rok N2 P15 B3", "rok N3 P14 B2", "rok N5 P13 B1", "t9"] * 2,
    "resend": greet + moves + ["rError:checksum mismatch, Last Line: 2", "rResend: 3", "rok", "t9", "t9", "rok T:20.0 /0.0", "rok", "rok"],
    "silence": greet + moves + ["t9"] * 40 + ["rok T:20.0 /0.0"],
    "reset": greet + moves[:4] + ["rok", "rstart", "t9", "m", "t9", "rok", "rok", "x", "c"],
    "busy": greet + ["eM400"] + ["recho:busy: processing", "t9"] * 5 + ["rok"],
}
for opt in (0, 1, 2, 9):
    for name, lines in scripts.items():
        open(os.path.join(out, "fuzz_protocol", "%s_%d" % (name, opt)), "wb").write(bytes([opt]) + ("\n".join(lines) + "\n").encode())
PY
echo "seeds: $(find "$out" -type f | wc -l) files in $out"
