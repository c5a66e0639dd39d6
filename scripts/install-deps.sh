#!/usr/bin/env bash
# Installs everything xlate5 needs to build and test on Debian 12 (bookworm), from Debian's packages only.
set -euo pipefail
pkgs=(build-essential cmake pkg-config
      libeigen3-dev libboost-dev libtomlplusplus-dev libspdlog-dev libfmt-dev
      doctest-dev libcli11-dev libserialport-dev libsystemd-dev
      printcore python3-serial
      man-db    # man-db: the manual page test renders xlate5(1) with man -l
      file      # cpack -G DEB reads the binaries' dependencies with file and dpkg-shlibdeps
      chromium      # the --preview test loads the page in headless Chromium (skipped without it)
      prusa-slicer) # the post-processing test slices with xlate5 as its script (skipped without it)
# `install-deps.sh fuzz` adds what the fuzz targets need (scripts/fuzz.sh): clang, libFuzzer and
# the sanitizer runtimes; and valgrind, for the benchmark's instruction counts (bench/instructions.sh).
# The test suite itself does not need them.
if [ "${1:-}" = fuzz ]; then pkgs+=(clang libclang-rt-14-dev valgrind); fi
missing=()
for p in "${pkgs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi
