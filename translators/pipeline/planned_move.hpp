// SPDX-License-Identifier: GPL-3.0-or-later
// The values the planner and the motion stage exchange, through translator.cpp (neither calls the
// other): the planner's output, PlannedMove, the value the motion stage takes (a tool-space move
// solved at both ends, joints and poses, with its E and feed terms; it owns its joints, the
// machine's first n of each array, so a stage may keep it, cut it into parts or hand it on); and
// what the motion stage made of it, MotionOutcome (where it ended: the next move's start) and
// MoveResult (the report's figures), which the planner takes on arrival. And the planner's
// joint-space output, JointStep and SetJoints, which translator.cpp hands through the compensation
// stage to the emitter: the planner writes no text.
#pragma once
#include <cstdint>
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

// A travel move that ended on another solution of its pose than the usual one.
enum class SolutionChange { None, Turns, Branch };

// What one move became, for the report and tests: the motion stage measures its pieces, the
// planner adds what it chose on the move's arrival, and the report's log takes it.
struct MoveResult {
    int pieces = 0;
    double tip_error = 0;    // mm, the largest sampled deviation of the firmware's path
    double angle_error = 0;  // degrees
    double feed_error = 0;   // relative: the tip's speed under the firmware over the programmed, - 1 (worst piece)
    std::vector<double> travel;  // degrees (or mm) each joint moves, summed over the pieces
    int pole_crossings = 0;      // the move changed branch across a pole
    std::vector<double> low, high;  // each joint's extremes over the move (its start and every piece's end)
    double minutes = 0;          // time the pieces take at the feeds written (no acceleration)
    SolutionChange change = SolutionChange::None;  // set by the planner
    bool prints = false;         // set by the planner: the move extrudes
    int rezeros = 0;             // G92s the planner had written after the move to re-zero a wound-up rotary
    std::uint64_t moves_written = 0;  // the emitter's count of move lines once the move was written (its output's place)
};

// What the motion stage made of a planned move, handed on (translator.cpp) to the planner, whose
// next move starts where this one ended.
struct MotionOutcome {
    // Not ok: nothing was written, and the message says where along the move it failed.
    IkResult result;
    // Set when the move's last part was split: the joints it ended at as that split solved them
    // (the machine's first n), which may not be q1: a tool-vector move's continuous solution may
    // arrive on the other branch or another turn, or the pole policy took it across to another
    // end. Unset: it ended on its own q1.
    std::optional<Joints> ended{};
    bool ok() const { return result.ok(); }
};

// A joint-space move (G0/G1 under G49) as the planner resolved it: the firmware is sent to `q`
// (nominal joints, the machine's first n), naming the joints the line names when their position
// is not known, with E and F as written.
struct JointStep {
    int gcode = 1;
    Joints q{};
    JointBits given = 0;
    std::optional<PassedNumber> e, f;
    bool inverse_time = false;  // G93: F is 1/minutes, written on every move
};

// A G92 as the planner resolved it: the firmware is told the joints in `which` are at `q` (nominal,
// the machine's first n), and E when given. Also the planner's re-zero of a wound-up rotary.
struct SetJoints {
    Joints q{};
    JointBits which = 0;
    std::optional<PassedNumber> e;
};

}  // namespace xlate5
