// SPDX-License-Identifier: GPL-3.0-or-later
// The planner's output, the value the motion stage takes: a tool-space move solved at both ends
// (joints and poses), with its E and feed terms. It owns its joints (the machine's first n of
// each array), so a stage may keep it, cut it into parts or hand it on.
#pragma once
#include <optional>
#include <vector>

#include "translators/kinematics/kinematics.hpp"
#include "translators/number.hpp"
#include "translators/pipeline/modes.hpp"

namespace xlate5 {

// A passage made in three joint-linear parts (pole_policy.hpp: PoleHold, turn): from the start to the joints
// `before` at move parameter `at` (the closest approach to the pole of the programmed axis's arc,
// kept off the move's very ends), there a turn in place to `after` (the tip held, the rotaries
// onto the other branch), then on to the passage's end.
struct PoleTurn {
    bool valid = false;
    double at = 0;
    std::vector<double> before, after;
};

struct PlannedMove {
    int gcode = 1;
    OrientationMode mode = OrientationMode::Angles;  // how the move is interpolated in tool space
    Joints q0{};                                     // start joints and pose
    Pose p0;
    Joints q1{};                                     // end joints (solved) and pose
    Pose p1;
    // The position solve's own end, when it gave one (valid): the split bounds the printed end
    // from it instead of an FK (used only when its joints are q1's).
    Kinematics::SolvedEnd end;
    JointBits commanded = 0;  // joints the line names: the emitter writes them when their firmware position is not known
    std::optional<PassedNumber> e;                   // E as written (mm, absolute or relative)
    bool e_relative = false;
    double e_start = 0;                              // absolute E before the move
    double feed = 0;                                 // programmed feed, mm/min (0: none yet)
    std::optional<PassedNumber> f;                   // F as written on this line (passed on under G49)
    double inverse_time = 0;                         // G93 input: the move's duration is 1/F minutes
    // The planner held the start off its programmed axis near a pole (pole_policy.hpp: hold): the
    // joints need not be on the continuous solution of p0's axis, and the move may first have to
    // join it (see MotionStage::join_from_held).
    bool start_held = false;
    // The orientation solutions of p1's axis, when the planner solved them (a tool vector's end):
    // the split takes them instead of solving that axis again.
    std::optional<Kinematics::Solutions> end_solutions;
    // A passage near a pole made with a half turn in place on the way (valid), its own copy.
    PoleTurn turn;
};

}  // namespace xlate5
