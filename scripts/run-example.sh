#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# Installs the dependencies, builds xlate5, and translates the bundled rw2 example
# (tool space, Andersons 2023's dialect) into joint space for stock Marlin, with its preview page
# (open it in a browser: the path, the tool and the joints); then turns the result back into tool
# space to show the round trip. Then the service: `xlate5 serve` with its virtual
# printer, Printrun's printcore streaming the same file into it as into a printer, and the
# commands the virtual printer executed compared with the offline translation.
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/install-deps.sh
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build build -j"$(nproc 2>/dev/null || echo 2)" --target xlate5
mkdir -p out
./build/cli/xlate5 --machine rw2 -i examples/rw2_flared_wall.gcode -o out/rw2_flared_wall.joints.gcode \
  --preview out/rw2_flared_wall.preview.html
./build/cli/xlate5 --machine rw2 --inverse -i out/rw2_flared_wall.joints.gcode -o out/rw2_flared_wall.roundtrip.gcode
echo "input  (tool space):  examples/rw2_flared_wall.gcode ($(wc -l < examples/rw2_flared_wall.gcode) lines)"
echo "output (joint space): out/rw2_flared_wall.joints.gcode ($(wc -l < out/rw2_flared_wall.joints.gcode) lines)"
echo "preview (open it in a browser): out/rw2_flared_wall.preview.html"
echo "round trip (the joints back in tool space, for any G-code viewer): out/rw2_flared_wall.roundtrip.gcode"
echo "--- first moves of the translated file:"
grep -m 12 '^G[01] ' out/rw2_flared_wall.joints.gcode
echo "--- the service: printcore -> xlate5 serve -> virtual printer"
/usr/bin/python3 tests/e2e/service_e2e.py ./build/cli/xlate5 rw2 examples/rw2_flared_wall.gcode printcore
