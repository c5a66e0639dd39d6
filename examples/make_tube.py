#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""A sliced tube for the keep-out workflow (ADD_IN team, 2015, figure 1): layers of
short G1 moves around a centre, with a keep-out item at the centre.

    python3 examples/make_tube.py [LAYERS] [STEPS_PER_LAYER] > examples/addin4_tube.gcode

writes the G-code to standard output and examples/addin4_tube_items.csv next to this script.
Defaults: 5 layers of 120 moves (radius 20 mm around X100 Y100, 0.2 mm layers)."""
import math
import os
import sys

layers = int(sys.argv[1]) if len(sys.argv) > 1 else 5
steps = int(sys.argv[2]) if len(sys.argv) > 2 else 120
cx, cy, r, h = 100.0, 100.0, 20.0, 0.2
e_per_mm = 0.033

out = ["; a tube around a keep-out item at X100 Y100 (make_tube.py)", "G90", "M83", "G28", "G0 Z5 F3000",
       f"G0 X{cx + r:.3f} Y{cy:.3f}"]
for layer in range(layers):
    z = h * (layer + 1)
    out.append(f"G0 Z{z:.3f}")
    for k in range(1, steps + 1):
        a0, a1 = 2 * math.pi * (k - 1) / steps, 2 * math.pi * k / steps
        x, y = cx + r * math.cos(a1), cy + r * math.sin(a1)
        e = 2 * r * math.sin((a1 - a0) / 2) * e_per_mm
        out.append(f"G1 X{x:.4f} Y{y:.4f} E{e:.5f} F1800")
out.append(f"G0 Z{h * layers + 5:.3f}")
sys.stdout.write("\n".join(out) + "\n")
with open(os.path.join(os.path.dirname(os.path.abspath(__file__)), "addin4_tube_items.csv"), "w") as f:
    f.write("# x, y, height of each keep-out item (mm)\n100, 100, 0\n")
