// SPDX-License-Identifier: GPL-3.0-or-later
// The modal state of G-code that both directions keep (the interpreter and the inverse
// pipeline each hold one). Data only; calls nothing.
#pragma once

namespace xlate5 {

struct Modes {
    bool absolute = true;     // G90 / G91
    bool inches = false;      // G20 / G21
    bool e_relative = false;  // Marlin 2 rule: the latest of G90/G91/M82/M83 decides
    int motion = -1;          // modal G0/G1/G2/G3 (-1: none yet)
    int plane = 17;           // G17 XY, G18 ZX, G19 YZ: the plane of arcs
    bool inverse_time = false;  // G93: F is 1/duration in minutes, per move
    double feed = 0;          // programmed feed (G94), mm/min; 0 until the first F
    double e_position = 0;    // absolute E (the inverse pipeline's; the forward planner keeps its own)
    double e_inch_carry = 0;  // relative E read in inches: what rounding to the dialect's decimals left over
    double unit() const { return inches ? 25.4 : 1.0; }
};

}  // namespace xlate5
