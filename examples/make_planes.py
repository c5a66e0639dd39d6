#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""Planar files for the 3+2 workflow of Coeytaux et al. (WPI Worcester 2017, sec. 3.2.5 and
4.1.5): a block printed upright, and a side sub-volume sliced flat along its own build
direction, to be joined on wpi5, and one file that prints a square in a tilted plane itself.

    python3 examples/make_planes.py

writes wpi5_base.gcode, wpi5_side.gcode and wpi5_tilted_square.gcode next to this script. Then:

    xlate5 --machine wpi5 join examples/wpi5_base.gcode examples/wpi5_side.gcode@1,0,1@0,0,4 -o part.gcode
    xlate5 --machine wpi5 -i examples/wpi5_tilted_square.gcode -o square.gcode
"""
import os

here = os.path.dirname(os.path.abspath(__file__))
h, e_per_mm = 0.2, 0.033


def squares(side, layers, feed=1200):
    """Layers of a square of `side` centred on the origin, relative E, a travel to each."""
    s = side / 2
    corners = [(s, -s), (s, s), (-s, s), (-s, -s)]
    out = []
    for layer in range(layers):
        z = h * (layer + 1)
        out.append(f"G0 X{-s:.3f} Y{-s:.3f} Z{z + 2:.3f} F3000")
        out.append(f"G1 Z{z:.3f} F600")
        for x, y in corners:
            out.append(f"G1 X{x:.3f} Y{y:.3f} E{side * e_per_mm:.5f} F{feed}")
    return out


def write(name, lines):
    with open(os.path.join(here, name), "w") as f:
        f.write("\n".join(lines) + "\n")


start = ["G21", "G90", "M83", "M104 S210", "M140 S60", "M109 S210", "G28"]
end = ["G91", "G0 Z5", "G90", "M104 S0", "M140 S0", "M84"]
write("wpi5_base.gcode", ["; the upright block (make_planes.py)"] + start + squares(20, 20) + end)
write("wpi5_side.gcode", ["; a side sub-volume, sliced flat along its own build direction (make_planes.py)"] + start + squares(8, 10) + end)
write("wpi5_tilted_square.gcode",
      ["; a square printed in a plane tilted 30 degrees about X (make_planes.py)"] + start[:6] +
      ["G0 X0 Y0 Z20 F3000", "G68.2 X0 Y0 Z0 I0 J30 K0", "G53.1"] + squares(20, 3) +
      ["G91", "G0 Z5", "G90", "G69", "M104 S0", "M140 S0", "M84"])
