#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# Installs everything xlate5 needs to build and test on Debian 12 (bookworm), from Debian's packages only.
set -euo pipefail
pkgs=(build-essential cmake pkg-config
      libeigen3-dev libboost-dev libtomlplusplus-dev libspdlog-dev libfmt-dev
      doctest-dev libcli11-dev libserialport-dev libsystemd-dev
      libfcl-dev libassimp-dev   # the collision check: FCL, and assimp to read machine meshes
      printcore python3-serial
      man-db    # man-db: the manual page test renders xlate5(1) with man -l
      file      # cpack -G DEB reads the binaries' dependencies with file and dpkg-shlibdeps
      libjs-three   # three.js and its OrbitControls, inlined into the --preview page at build time
      chromium      # the --preview test loads the page in headless Chromium (skipped without it)
      prusa-slicer  # the post-processing test slices with xlate5 as its script (skipped without it)
      lintian)      # the package test checks the .deb with it (skipped without it)
# `install-deps.sh fuzz` adds what the fuzz targets need (scripts/fuzz.sh): clang, libFuzzer and
# the sanitizer runtimes; and valgrind, for the benchmark's instruction counts (bench/instructions.sh).
# The test suite itself does not need them.
if [ "${1:-}" = fuzz ]; then pkgs+=(clang libclang-rt-14-dev valgrind); fi
missing=()
for p in "${pkgs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#pkgs[@]} Debian packages are installed"
  exit 0
fi
SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
# apt and dpkg say several lines per package (hundreds on a fresh system): they go to a log, and
# this script says in one line what it installs and how much, and where the log is.
log=$(mktemp -t xlate5-apt.XXXXXX.log)
run_apt() {
  if ! DEBIAN_FRONTEND=noninteractive $SUDO apt-get "$@" >>"$log" 2>&1; then
    echo "install-deps: apt-get $1 failed; the end of its log ($log):" >&2
    tail -n 20 "$log" >&2
    exit 1
  fi
}
run_apt update -q
# The download, from apt's own list of what it would fetch (the missing packages and what they
# pull in): its size is what decides how long this takes.
uris=$(DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends --print-uris "${missing[@]}" 2>>"$log" || true)
count=$(grep -c "^'" <<<"$uris" || true)
megabytes=$(awk "/^'/ { s += \$3 } END { printf \"%.1f\", s / 1e6 }" <<<"$uris")
echo "install-deps: installing ${missing[*]} with apt: $count packages with what they need, about $megabytes MB to download" \
     "(a few minutes on a fast line, longer on a slow one; Chromium and PrusaSlicer are the large ones); log: $log"
start=$SECONDS
run_apt install -y -q --no-install-recommends "${missing[@]}"
echo "install-deps: done in $((SECONDS - start)) s"
