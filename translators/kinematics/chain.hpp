// SPDX-License-Identifier: GPL-3.0-or-later
// The general chain, compiled for the walk: the loader's elements with the shortcuts their
// numbers allow. The walk itself and the general solves (the readable specification every fast
// path is held to) are in chain.cpp. May call: the machine data.
#pragma once
#include <Eigen/Core>
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

// The orientation structure (kinematics.cpp's load_orientation): u = R_part^T R_tool u0 written as
// u' = G0^T u = R(w1, s1 q1) R(w2, s2 q2) p, the fixed rotations folded into the axes.
struct OrientationFrame {
    std::vector<int> rotary;         // rotary joint indices in the order of the orientation product
    std::vector<double> sign;        // +1 tool chain, -1 part chain (the part rotation enters inverted)
    std::vector<Eigen::Vector3d> w;  // rotation axes in the frame of u' = G0^T u
    Eigen::Matrix3d g0 = Eigen::Matrix3d::Identity();
    Eigen::Vector3d p = Eigen::Vector3d::UnitZ();
    bool flip = false;  // see Kinematics::has_flip
};

// The position solve's constants: its unknowns, the Jacobian when fixed, the scalar solve's plan.
struct PositionSolve {
    std::vector<int> linear;         // the first three linear joints: the position solve's unknowns
    bool constant_jacobian = false;  // no rotation ahead of a linear joint: its inverse is fixed
    double jacobian_inverse[9] = {};  // that inverse, row by row (constant_jacobian)
    // The scalar solve (solve_scalar): whether each unknown's linear joint is in the tool chain
    // and in the part chain; a tool chain of fresh linear links alone, and the identity times the
    // tool axis.
    struct Column {
        bool tool = false, part = false;
    };
    Column cols[3];
    bool tool_plain = false;
    double tool_up[3] = {};
};
PositionSolve load_position_solve(const Machine& machine, const std::vector<ChainLink>& part_links,
                                  const std::vector<ChainLink>& tool_links);

// For the solve's SolvedEnd: each rotary element's axis line, in forward()'s walk order, is
// moved by the linear joints ahead of it in its own chain (a mask of joints); the tip by those
// of the tool chain. `on` false when a linear joint appears twice (a machine built by hand) or the
// path bound's near_end would not cover every joint that shifts the tip.
struct SolvedEndPlan {
    struct LineShift {
        bool tool = false;    // in the tool chain (else the part chain)
        unsigned linear = 0;  // bit j: linear joint j is ahead of it in that chain
    };
    std::vector<LineShift> line_shifts;
    std::vector<int> tool_linear;  // the tool chain's linear joints (they carry the tip)
    bool on = false;
};

}  // namespace xlate5
