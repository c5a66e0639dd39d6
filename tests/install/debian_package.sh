#!/usr/bin/env bash
# The Debian package as a user gets it: cpack builds it from this build tree, dpkg -x unpacks it
# into an empty directory, and the unpacked program runs: --version, and the packaged example
# translated with a machine file from the unpacked share directory, found by name next to the
# program, exactly as the build tree's program translates it.
# Usage: debian_package.sh BUILD_DIR XLATE5 EXAMPLE.gcode
set -euo pipefail
build=$1 built=$2 source_example=$3
fail() { echo "FAIL: $*" >&2; exit 1; }
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

(cd "$build" && cpack -G DEB -B "$work/pkg" >"$work/cpack.log" 2>&1) || { cat "$work/cpack.log" >&2; fail "cpack"; }
debs=("$work"/pkg/*.deb)
[ ${#debs[@]} -eq 1 ] && [ -f "${debs[0]}" ] || fail "cpack made no single .deb: ${debs[*]}"
deb=${debs[0]}
dpkg-deb --field "$deb" Package | grep -qx xlate5 || fail "Package field"
depends=$(dpkg-deb --field "$deb" Depends)
grep -q libserialport <<<"$depends" || fail "Depends lacks libserialport: $depends"

root="$work/root"
mkdir "$root"
dpkg -x "$deb" "$root"
for f in usr/bin/xlate5 usr/share/xlate5/machines/rw2.toml usr/share/xlate5/xlate5.toml.example \
         usr/lib/systemd/system/xlate5@.service usr/lib/sysusers.d/xlate5.conf usr/share/man/man1/xlate5.1.gz \
         usr/share/bash-completion/completions/xlate5 usr/share/doc/xlate5/README.md usr/share/doc/xlate5/machines.md \
         usr/share/doc/xlate5/examples/rw2_flared_wall.gcode; do
  [ -e "$root/$f" ] || fail "$f not in the package"
done
example="$root/usr/share/doc/xlate5/examples/$(basename "$source_example")"
cmp -s "$source_example" "$example" || fail "the packaged example differs from $source_example"
grep -q '^ExecStart=/usr/bin/xlate5 serve ' "$root/usr/lib/systemd/system/xlate5@.service" || fail "the unit does not run /usr/bin/xlate5"
grep -q 'file:///usr/share/doc/xlate5/' "$root/usr/lib/systemd/system/xlate5@.service" || fail "the unit's documentation path"
# The installed unit's sandbox (docs/limits.md): systemd's exposure score at most 1.5.
if command -v systemd-analyze >/dev/null; then
  score=$(cd "$root/usr/lib/systemd/system" && systemd-analyze security --offline=true ./xlate5@.service 2>&1 | sed -n 's/.*Overall exposure level for [^:]*: \([0-9.]*\).*/\1/p')
  [ -n "$score" ] || fail "systemd-analyze gave no exposure score"
  awk -v s="$score" 'BEGIN { exit !(s <= 1.5) }' || fail "the unit's exposure score is $score (at most 1.5)"
fi
if strings "$root/usr/bin/xlate5" | grep -qF "$build"; then fail "the packaged program names the build directory"; fi

# A clean environment: no user or override machine directory.
run() { env -i HOME="$work/home" PATH=/usr/bin:/bin "$root/usr/bin/xlate5" "$@"; }
version=$(run --version)
[[ $version =~ ^xlate5\ [0-9]+\.[0-9]+\.[0-9]+$ ]] || fail "--version printed '$version'"
run machines | grep -q '^rw2 ' || fail "the unpacked program does not list its rw2"

# The same translation as the build tree's program, from the unpacked machine file by path ...
run --machine "$root/usr/share/xlate5/machines/rw2.toml" -i "$example" -o "$work/by-path.gcode"
"$built" --machine rw2 -i "$example" -o "$work/built.gcode"
cmp -s "$work/built.gcode" "$work/by-path.gcode" || fail "the unpacked program translates differently"
[ "$(grep -c '^G1 ' "$work/built.gcode")" -gt 100 ] || fail "the example translated to too few moves"
# ... and by name, found in the unpacked share directory: there la is changed to 29, and the
# output is the build tree's with --set la=29.
sed -i 's/^la = 26\.5\b/la = 29/' "$root/usr/share/xlate5/machines/rw2.toml"
grep -q '^la = 29' "$root/usr/share/xlate5/machines/rw2.toml" || fail "rw2.toml has no 'la = 26.5' line to change"
run --machine rw2 -i "$example" -o "$work/by-name.gcode"
"$built" --machine rw2 --set la=29 -i "$example" -o "$work/built-29.gcode"
cmp -s "$work/built-29.gcode" "$work/by-name.gcode" || fail "by name, the unpacked program did not use its own share directory"
cmp -s "$work/built.gcode" "$work/by-name.gcode" && fail "la = 29 changed nothing"
echo "debian package: $(basename "$deb"), $(stat -c %s "$deb") bytes, unpacked program ok"
