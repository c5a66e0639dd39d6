#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# Soak of the service (bench/soak.py): LINES (default 10,000,000) through `xlate5 serve` and its
# virtual printer with faults, executed commands compared with the offline translation, memory
# sampled. At the lowest priority; hours for the default on a small machine. Not run in CI.
# Usage: bench/soak.sh [LINES] [PRINT_LINES]
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
[ -x "$root/build/cli/xlate5" ] || { cmake -S "$root" -B "$root/build" -DCMAKE_BUILD_TYPE=Release >/dev/null; cmake --build "$root/build" -j2 --target xlate5; }
exec nice -n 19 /usr/bin/python3 "$root/bench/soak.py" "$root/build/cli/xlate5" "${1:-10000000}" "${2:-100000}"
