#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""A small waypoint table as curved-layer research tools write it (x y z nx ny nz per line, the
vector not of unit length): a conical wall whose tool axis leans outward with the wall.

    python3 examples/make_waypoints.py > examples/cone_waypoints.txt
"""
import math

print("# x y z nx ny nz (mm; the vector is the tool axis, any length)")
for layer in range(8):
    if layer:
        print()  # a blank line: travel to the next layer's first point
    z = 0.3 + 0.3 * layer
    r = 15 + 0.15 * layer
    for k in range(73):
        a = 2 * math.pi * k / 72
        s = 0.5 + (k % 5) * 0.4  # lengths 0.5..2.1: normalised by the reader
        print(f"{r * math.cos(a):.4f} {r * math.sin(a):.4f} {z:.4f} "
              f"{0.45 * math.cos(a) * s:.5f} {0.45 * math.sin(a) * s:.5f} {s:.5f}")
