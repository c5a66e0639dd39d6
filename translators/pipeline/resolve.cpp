// SPDX-License-Identifier: GPL-3.0-or-later
// The planner's first step: commands' "as before" filled in from the planner's state.
// What it may call: see resolve.hpp.
#include "translators/pipeline/resolve.hpp"

#include <bit>
#include <string>

#include "translators/constants.hpp"
#include "translators/error.hpp"
#include "translators/pipeline/arcs.hpp"

namespace xlate5 {

Resolver::Resolver(const Kinematics& kinematics, const PlannerState& state)
    : machine_(kinematics.machine()), angles_{kinematics.rotary_joints()}, state_(state) {
    for (std::size_t j = 0; j < machine_.joints.size(); ++j) joint_bits_ |= 1u << j;
}

int Resolver::start_arc(const cmd::Arc& c) {
    const PlannerState& at = state_;
    Arc a;
    a.clockwise = c.clockwise;
    a.plane = c.plane;
    // Inside a tilted plane the arc and its G17-G19 are the plane's.
    const Eigen::Vector3d program = at.pose.tip - at.offset;
    a.start = c.tilted ? c.tilted->to_plane(program) : program;
    a.end = a.start;
    for (std::size_t i = 0; i < 3; ++i)
        if (c.end.given & (1u << i)) a.end[Eigen::Index(i)] = c.end.relative ? a.start[Eigen::Index(i)] + c.end.value[i] : c.end.value[i];
    a.by_radius = c.by_radius;
    a.offset_a = c.offset_a;
    a.offset_b = c.offset_b;
    a.radius = c.radius;
    a.turns = c.turns;
    arc_bound_ = pieces_bound(machine_.motion.max_pieces);
    if (auto why = arc_chords(a, 0.5 * machine_.motion.tolerance, chord_ends_, arc_bound_); !why.empty()) throw LineError(c.column, why);
    angles_.programmed(at, arc_angles_);  // rotary words are programmed angles
    arc_e0_ = at.e;
    arc_ = &c;
    return int(chord_ends_.size());
}

// Each chord is an absolute, metric G1 with its own words: X Y Z in the arc's frame, the rotaries
// turned linearly from the arc's start, E shared out (relative: equal chords, equal shares), F on
// the first.
cmd::ToolMove Resolver::chord(int k) const {
    const cmd::Arc& a = *arc_;
    const int chords = int(chord_ends_.size());
    const double f = double(k) / chords;
    const Eigen::Vector3d& p = chord_ends_[std::size_t(k - 1)];
    cmd::ToolMove mv;
    mv.gcode = 1;
    mv.column = a.column;
    mv.mode = a.mode;
    mv.xyz.value = {p.x(), p.y(), p.z()};
    mv.xyz.given = 7;
    mv.plane = a.tilted;
    mv.reads_angles = a.mode != OrientationMode::Vector;
    const Joints& q_start = arc_angles_;
    for (cmd::JointBits b = a.angles_given; b != 0; b &= b - 1) {
        const std::size_t j = std::size_t(std::countr_zero(b));
        const double target = a.absolute ? a.angles[j] : q_start[j] + a.angles[j];
        mv.angles[j] = q_start[j] + (target - q_start[j]) * f;
    }
    mv.angles_given = a.angles_given;
    if (a.tilted && a.tilted->tool_turned) {
        // After G53.1 every move inside the plane holds the tool on the plane's +Z.
        mv.any_ijk = true;
        mv.axis = a.tilted->normal();
        mv.mode = OrientationMode::Vector;
    }
    if (a.e) {
        const bool last = k == chords;
        const double e_total = a.e->value, e0 = arc_e0_;
        double v;
        if (a.e_relative) v = e_total / chords;
        else v = e0 + (e_total - e0) * f;
        mv.e = last && !a.e_relative ? PassedNumber{e_total, a.e->text} : PassedNumber{v, {}};
    }
    if (k == 1) mv.f = a.f;
    // Under G93 every feed move needs its F (the interpreter's check, here per chord): only the
    // first chord has one.
    if (a.inverse_time && !mv.f) throw LineError(a.column, "under G93 every feed move (G1, G2, G3) needs its F (1/minutes)");
    cmd::JointBits rotary = 0, linear = 0;
    for (std::size_t j = 0; j < machine_.joints.size(); ++j) (machine_.joints[j].rotary ? rotary : linear) |= 1u << j;
    mv.commanded = linear | a.angles_given | (mv.any_ijk ? rotary : 0);
    mv.e_relative = a.e_relative;
    mv.feed = a.feed;
    mv.inverse_time = a.inverse_time;
    return mv;
}

void Resolver::check_arc_lines(long lines) const {
    if (lines > arc_bound_)
        throw LineError(arc_->column, "the arc needs more than " + std::to_string(arc_bound_) +
                                          " output lines to stay within the tolerance (the bound on pieces per input line)");
}

}  // namespace xlate5
