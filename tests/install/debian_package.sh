#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# The Debian package as a user gets it: cpack builds it from this build tree, dpkg -x unpacks it
# into an empty directory, and the unpacked program runs: --version, and the packaged example
# translated with a machine file from the unpacked share directory, found by name next to the
# program, exactly as the build tree's program translates it. Every document the README names is
# in it, with Debian's copyright file and changelog; its maintainer scripts make the xlate5 user
# and stop running xlate5@ instances on removal (run against stand-in commands that record what
# they are asked); lintian (when installed) finds no error.
# Usage: debian_package.sh BUILD_DIR XLATE5 EXAMPLE.gcode SOURCE_DIR
set -euo pipefail
build=$1 built=$2 source_example=$3 source=$4
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
# The documents the README sends a user to, the Cura script, the licence and the changelog.
docs=$(grep -o 'docs/[a-z0-9-]*\.md' "$source/README.md" | sort -u)
[ "$(wc -l <<<"$docs")" -ge 6 ] || fail "the README names too few documents: $docs"
for f in $docs; do
  cmp -s "$source/$f" "$root/usr/share/doc/xlate5/$(basename "$f")" || fail "$f (named in the README) is not in the package"
done
cmp -s "$source/examples/cura/Xlate5.py" "$root/usr/share/doc/xlate5/examples/cura/Xlate5.py" || fail "the Cura script is not in the package"
copyright="$root/usr/share/doc/xlate5/copyright"
[ -f "$copyright" ] || fail "no copyright file"
head -1 "$copyright" | grep -qx 'Format: https://www.debian.org/doc/packaging-manuals/copyright-format/1.0/' || fail "copyright: not the machine-readable format 1.0"
grep -qx 'License: GPL-3+' "$copyright" || fail "copyright: no GPL-3+ licence"
grep -q '/usr/share/common-licenses/GPL-3' "$copyright" || fail "copyright: does not point to the GPL-3 text"
changelog="$root/usr/share/doc/xlate5/changelog.gz"
[ -f "$changelog" ] || fail "no changelog.gz"
pkg_version=$(dpkg-deb --field "$deb" Version)
gzip -dc "$changelog" > "$work/changelog"
# The newest entry's version, the first line's "xlate5 (VERSION) ...".
[ "$(sed -n '1s/^xlate5 (\([^)]*\)).*/\1/p' "$work/changelog")" = "$pkg_version" ] || fail "the changelog's version is not the package's ($pkg_version)"
if command -v dpkg-parsechangelog >/dev/null; then
  [ "$(dpkg-parsechangelog -l "$work/changelog" -SVersion)" = "$pkg_version" ] || fail "dpkg-parsechangelog reads another version"
fi
maintainer=$(dpkg-deb --field "$deb" Maintainer)
grep -q '@invalid>' <<<"$maintainer" && fail "Maintainer $maintainer"

# The maintainer scripts, in the control archive, executable.
control="$work/control"
dpkg-deb -e "$deb" "$control"
for f in postinst prerm postrm; do
  [ -x "$control/$f" ] || fail "no executable $f in the package"
  sh -n "$control/$f" || fail "$f is not valid sh"
done
# Run against stand-ins that record their arguments: postinst configure makes a system user
# xlate5 in dialout when there is none, and only adds it to dialout when there is one.
stubs="$work/stubs" calls="$work/calls"
mkdir "$stubs"
for c in adduser systemctl deb-systemd-invoke; do
  printf '#!/bin/sh\necho "%s $*" >> "%s"\n' "$c" "$calls" > "$stubs/$c"
done
printf '#!/bin/sh\n[ -n "$XLATE5_TEST_USER_EXISTS" ] && [ "$1 $2" = "passwd xlate5" ] && echo "xlate5:x:999:999::/nonexistent:/usr/sbin/nologin" && exit 0\nexit 2\n' > "$stubs/getent"
chmod +x "$stubs"/*
: > "$calls"
PATH="$stubs:/usr/bin:/bin" "$control/postinst" configure
grep -q '^adduser --system .*--home /nonexistent .* xlate5$' "$calls" || fail "postinst made no system user xlate5: $(cat "$calls")"
grep -qx 'adduser --quiet xlate5 dialout' "$calls" || fail "postinst did not put xlate5 in dialout: $(cat "$calls")"
: > "$calls"
XLATE5_TEST_USER_EXISTS=1 PATH="$stubs:/usr/bin:/bin" "$control/postinst" configure
grep -q -- '--system' "$calls" && fail "postinst made the user again: $(cat "$calls")"
grep -qx 'adduser --quiet xlate5 dialout' "$calls" || fail "postinst (user there) did not check dialout"
# prerm stops the running instances on remove, not on upgrade; it needs a running systemd
# (/run/systemd/system), given here in a private mount namespace (root only).
if [ "$(id -u)" = 0 ] && unshare -m true 2>/dev/null; then
  for action in remove upgrade; do
    : > "$calls"
    unshare -m sh -c 'mount -t tmpfs none /run && mkdir -p /run/systemd/system && PATH="$1:/usr/bin:/bin" "$2" "$3"' \
      sh "$stubs" "$control/prerm" "$action" || fail "prerm $action failed"
    if [ $action = remove ]; then
      grep -qx "deb-systemd-invoke stop xlate5@\*.service" "$calls" || fail "prerm remove stopped nothing: $(cat "$calls")"
    else
      [ ! -s "$calls" ] || fail "prerm upgrade stopped instances: $(cat "$calls")"
    fi
  done
  : > "$calls"
  unshare -m sh -c 'mount -t tmpfs none /run && mkdir -p /run/systemd/system && PATH="$1:/usr/bin:/bin" "$2" remove' \
    sh "$stubs" "$control/postrm" || fail "postrm remove failed"
  grep -qx 'systemctl --system daemon-reload' "$calls" || fail "postrm remove: no daemon-reload: $(cat "$calls")"
else
  echo "prerm and postrm under a running systemd: skipped (needs root for a private /run)"
fi
# Without systemd running (a chroot, a container), they do nothing and succeed.
: > "$calls"
if [ ! -d /run/systemd/system ]; then
  PATH="$stubs:/usr/bin:/bin" "$control/prerm" remove
  PATH="$stubs:/usr/bin:/bin" "$control/postrm" purge
  [ ! -s "$calls" ] || fail "prerm/postrm called systemd without one running: $(cat "$calls")"
fi

if command -v lintian >/dev/null; then
  lintian --no-tag-display-limit "$deb" > "$work/lintian.txt" 2>&1 || true
  if grep -q '^E: ' "$work/lintian.txt"; then cat "$work/lintian.txt" >&2; fail "lintian reports errors"; fi
  echo "lintian: $(grep -c '^W: ' "$work/lintian.txt" || true) warnings, no errors"
else
  echo "lintian: not installed, skipped"
fi

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
