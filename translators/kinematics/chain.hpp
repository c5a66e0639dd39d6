// SPDX-License-Identifier: GPL-3.0-or-later
// The general chain, compiled for the walk: the loader's elements with the shortcuts their
// numbers allow. The walk itself and the general solves (the readable specification every fast
// path is held to) are in chain.cpp. May call: the machine data.
#pragma once
#include <vector>

#include "translators/machine/machine.hpp"

namespace xlate5 {

// A chain element compiled for the walk in chain.cpp: the loader's element with the shortcuts
// its numbers allow, which give the same results to the last bit, up to the sign of a zero (a
// product term that is an exact zero left out, a product with the identity skipped, an element
// that changes nothing dropped).
struct ChainLink {
    enum class Kind : unsigned char { Fixed, Shift, Linear, Rotary, RotaryX, RotaryY, RotaryZ } kind = Kind::Fixed;
    bool fresh = false;  // nothing ahead of it in its chain rotates: the walk's rotation is still the identity
    bool shifts = true;  // Fixed: a translation; Rotary: its axis misses the origin (else t is left as it is)
    int joint = -1;
    double sign = 1;     // RotaryX/Y/Z: the axis is +1 or -1 times that coordinate axis, exactly
    double axis[3] = {}, point[3] = {}, shift[3] = {};
    double rot[9] = {};  // Fixed: its rotation, row by row (Shift: the identity, not stored)
};

// The walk's form of a chain.
std::vector<ChainLink> compile_chain(const std::vector<ChainElement>& chain);

}  // namespace xlate5
