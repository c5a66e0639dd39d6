#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""A bent tube printed as one spiral for rw2, in tool-vector form: the first layers are flat
(tool axis vertical, where rw2's A is free), then the tube bends toward +X with radius R, so the
tool axis leans over slowly in the XZ plane (A = 0, B growing). The head is at home (A = -168,
its min switch) when the print starts: at the pole the planner has to choose the A the coming
moves need (A near 0; A = +-180 is past the limits).

    python3 examples/make_bent_tube.py [REVOLUTIONS] [STEPS_PER_REV] [BEND_DEG] > bent_tube.gcode
    xlate5 --machine rw2 -i bent_tube.gcode -o joints.gcode

Defaults: 40 revolutions of 60 moves, 3 flat, bent by 15 degrees in all."""
import math
import sys

revs = int(sys.argv[1]) if len(sys.argv) > 1 else 40
steps = int(sys.argv[2]) if len(sys.argv) > 2 else 60
bend = math.radians(float(sys.argv[3])) if len(sys.argv) > 3 else math.radians(15.0)
flat = 3                      # revolutions printed upright
cx, cy, r, h = 110.0, 110.0, 10.0, 0.3
e_per_mm = 0.033
s_flat = flat * h
bend_radius = (revs - flat) * h / bend if revs > flat else 1e9


def pose(t):
    """Tip and tool axis after t revolutions of the spiral."""
    s = t * h                           # length along the tube's centre line
    theta = max(0.0, s - s_flat) / bend_radius
    centre = (cx + bend_radius * (1 - math.cos(theta)), cy, min(s, s_flat) + bend_radius * math.sin(theta))
    axis = (math.sin(theta), 0.0, math.cos(theta))
    e1 = (math.cos(theta), 0.0, -math.sin(theta))  # in the layer's plane, across the bend
    phi = 2 * math.pi * t
    tip = tuple(centre[i] + r * (math.cos(phi) * e1[i] + math.sin(phi) * (0, 1, 0)[i]) for i in range(3))
    return tip, axis


def words(tip, axis):
    return (f"X{tip[0]:.4f} Y{tip[1]:.4f} Z{tip[2] + h:.4f} "
            f"I{axis[0]:.7f} J{axis[1]:.7f} K{axis[2]:.7f}")


out = ["; bent tube for rw2 (make_bent_tube.py): vertical start, leaning over in XZ", "G21", "G90", "M83", "G43.5"]
tip, axis = pose(0)
out.append(f"G0 {words(tip, axis)} F3000")  # line 6: the travel move to the start
last = tip
for k in range(1, revs * steps + 1):
    tip, axis = pose(k / steps)
    e = math.dist(tip, last) * e_per_mm
    out.append(f"G1 {words(tip, axis)} E{e:.5f}" + (" F1200" if k == 1 else ""))
    last = tip
out.append("G0 Z{:.3f}".format(last[2] + h + 5))
sys.stdout.write("\n".join(out) + "\n")
