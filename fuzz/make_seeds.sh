#!/usr/bin/env bash
# Writes the seed corpora of the fuzz targets into DIR/<target>/ from what is at hand when run:
# the shared third-party corpus (../shared/corpus, when present; its files are never copied into
# the tree), the examples and the bundled machine files. Each seed starts with the selector bytes
# its target reads (fuzz/*.cpp), spread over the machines and modes.
# Usage: fuzz/make_seeds.sh DIR [CORPUS_DIR]
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
out="$1"
corpus="${2:-$root/../shared/corpus}"
mkdir -p "$out"/{fuzz_translate,fuzz_machine_file,fuzz_compensation,fuzz_calibrate}
tmp="$(mktemp -d)"; trap 'rm -rf "$tmp"' EXIT

# fuzz_translate: G-code in pieces of about 3 KB (libFuzzer works on short inputs), at most 24
# pieces a file, each under a different machine and configuration byte.
gcode=("$root"/examples/*.gcode)
[ -d "$corpus" ] && while IFS= read -r -d '' f; do gcode+=("$f"); done \
  < <(find "$corpus" -type f \( -name '*.gcode' -o -name '*.ngc' -o -name '*.txt' -o -name '*.cls' \) -print0)
n=0
for f in "${gcode[@]}"; do
  rm -f "$tmp"/piece.*
  head -c 400000 "$f" | split -C 3000 -a 4 - "$tmp/piece."
  k=0
  for p in "$tmp"/piece.*; do
    [ $k -ge 24 ] && break
    printf "\\x$(printf %02x $((n % 6)))\\x$(printf %02x $(((n / 6) % 64)))" > "$out/fuzz_translate/seed_$n"
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
echo "seeds: $(find "$out" -type f | wc -l) files in $out"
