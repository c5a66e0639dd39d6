#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""Writes the bundled examples (run it again after changing it; the outputs are committed).

rw2_flared_wall.gcode: a C-shaped wall that flares outward as it grows, in Andersons 2023's dialect
(G1 X Y Z A B E: tip plus head angles, G43.4 being rw2's start mode). The nozzle leans
radially outward by B; A follows the azimuth within rw2's +-168 degree cable limit, so each layer
is an arc of 300 degrees printed back and forth.

pentarod_dome.gcode: a dome shell in Grutle 2015's vector dialect (G1 X Y Z I J K F E), the tool
axis normal to the surface, printed upside down: a bowl, from its bottom on the plate up to its
rim 8.6 mm above it, the tool along the inner normal (up to 48 degrees from the plate's). Grutle
puts the origin where the rotary axes meet and calibrates the plate's top into it (sec. 3.1.3,
5.2.1: "the nozzle at the given intersection point is barely touching the print plate"), so a
part lies at Z >= 0; the dome printed the right way up from its apex on the plate ran its rings
down to Z -12.2, through the plate. The bowl tilts most where it is highest, as the thesis asks
(sec. 3.3.3, 5.1: the nozzle cannot reach the plate at large A). It stops at 48 degrees: at 52
the nozzle mount of tests/bodies/pentarod.toml (a guess, 60 mm wide from 25 mm above the tip)
reaches over the bowl onto its far rim.

Both start the way Andersons 2023's start code does: after homing, the tip travels to above the first
point at CLEARANCE mm and only then comes down onto the bed, so no travel crosses the bed low
(rw2 homes Z at its top; pentarod homes with the nozzle on the plate, so it lifts first).
"""
import math
import re

CLEARANCE = 10.0   # mm above the bed for the first travel

def rw2():
    out = ["; xlate5 example: flared C-shaped wall for rw2 (tip + head angles, Andersons 2023 dialect)",
           "G21", "G90", "M83", "M104 S215", "M140 S60",
           "G28 ; home all axes", "G92 A-168 ; A homes at its min switch", "G1 A0 B0 F1200",
           "M190 S60", "M109 S215", "G92 E0"]
    cx, cy, r0, h = 110.0, 110.0, 30.0, 0.3
    layers, steps = 20, 48
    prev = None
    for layer in range(layers):
        z = h * (layer + 1)
        tilt = 1.5 * layer                      # degrees of outward lean
        r = r0 + z * math.tan(math.radians(tilt))
        idx = range(steps + 1) if layer % 2 == 0 else range(steps, -1, -1)
        out.append(f";LAYER:{layer}")
        for n, i in enumerate(idx):
            phi = -150.0 + 300.0 * i / steps   # azimuth of the point, degrees
            x = cx + r * math.cos(math.radians(phi))
            y = cy + r * math.sin(math.radians(phi))
            a = -phi                            # u_xy = (cos A, -sin A) points along the azimuth
            if n == 0:
                if layer == 0:  # above the first point first, then straight down
                    out.append(f"G0 X{x:.3f} Y{y:.3f} Z{CLEARANCE:.3f} A{a:.2f} B{tilt:.2f} F3000")
                out.append(f"G0 X{x:.3f} Y{y:.3f} Z{z:.3f} A{a:.2f} B{tilt:.2f} F3000")
            else:
                e = 0.033 * math.dist((x, y, z), prev)
                out.append(f"G1 X{x:.3f} Y{y:.3f} Z{z:.3f} A{a:.2f} B{tilt:.2f} E{e:.5f} F1200")
            prev = (x, y, z)
    out += ["G1 Z20 F600", "M104 S0", "M140 S0", "M84"]
    return out

def pentarod():
    out = ["; xlate5 example: dome shell for pentarod (tip + tool vector, Grutle 2015 dialect)",
           "G21", "G90", "M82", "G28", f"G0 Z{CLEARANCE:.3f} F3000 ; lift off the plate", "G92 E0"]
    R, e = 25.0, 0.0
    prev = None
    for ring in range(1, 13):  # to 48 degrees (below)
        polar = math.radians(4.0 * ring)
        for i in range(73):
            az = math.radians(5.0 * i)
            # The bowl's surface about its centre (0, 0, R + 0.3), and its inner normal.
            n = (-math.sin(polar) * math.cos(az), -math.sin(polar) * math.sin(az), math.cos(polar))
            p = (-R * n[0], -R * n[1], R - R * n[2] + 0.3)
            if prev is None:  # above the first point first, then straight down
                out.append(f"G0 X{p[0]:.3f} Y{p[1]:.3f} Z{CLEARANCE:.3f} I{n[0]:.6f} J{n[1]:.6f} K{n[2]:.6f} F3000")
            if prev is None or i == 0:
                out.append(f"G0 X{p[0]:.3f} Y{p[1]:.3f} Z{p[2]:.3f} I{n[0]:.6f} J{n[1]:.6f} K{n[2]:.6f} F3000")
            else:
                e += 0.033 * math.dist(p, prev)
                out.append(f"G1 X{p[0]:.3f} Y{p[1]:.3f} Z{p[2]:.3f} I{n[0]:.6f} J{n[1]:.6f} K{n[2]:.6f} E{e:.5f} F900")
            prev = p
    out += ["G0 Z40 F3000", "M84"]
    return out

def no_negative_zero(lines):  # "J-0.000000" reads as 0 but looks like a sign error
    return [re.sub(r"-(0\.0+)(?![0-9])", r"\1", line) for line in lines]

for name, lines in (("rw2_flared_wall.gcode", rw2()), ("pentarod_dome.gcode", no_negative_zero(pentarod()))):
    with open(name, "w") as f:
        f.write("\n".join(lines) + "\n")
