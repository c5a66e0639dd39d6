// SPDX-License-Identifier: GPL-3.0-or-later
// The planner stage's first step: a command's "as before" and relative words filled in from where
// the machine is (the planner's state: joints, pose, the G92 program frame, E), so that the
// interpreter never reads that state. A tool move becomes the fully stated move the planner (or
// the keep-out stage before it) takes, handed on by translator.cpp; an arc becomes its chords,
// cut from where the tool is.
// Reads the planner's state, changes nothing; holds no stage. May call: arcs (the chords), the
// planner's angle map (the programmed angles of the joints the state is at).
#pragma once
#include <bit>
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "translators/pipeline/commands.hpp"
#include "translators/pipeline/planner.hpp"

namespace xlate5 {

class Resolver {
public:
    Resolver(const Kinematics& kinematics, const PlannerState& state);

    // The move `mv` says, from where the machine is now. Valid until the next call.
    const ToolMove& tool_move(const cmd::ToolMove& mv);

    // An arc from where the tool is now: cut into chords (throws LineError when it cannot be);
    // returns their number. chord(k) is then the k-th (1-based), an absolute move in the arc's
    // frame, to be resolved (tool_move) when the chords before it have run; throws LineError
    // under G93 for a chord without F (all but the first).
    int start_arc(const cmd::Arc& arc);
    cmd::ToolMove chord(int k) const;
    // The arc's output so far (`lines`, after a chord) is past the bound on pieces per input
    // line: throws LineError.
    void check_arc_lines(long lines) const;

private:
    const Machine& machine_;
    const AngleMap angles_;  // programmed angles <-> joints
    const PlannerState& state_;
    ToolMove resolved_;
    cmd::JointBits joint_bits_ = 0;  // one bit for each of the machine's joints
    // The arc started last: its command, chord ends, start angles and E.
    const cmd::Arc* arc_ = nullptr;
    std::vector<Eigen::Vector3d> chord_ends_;
    Joints arc_angles_;
    double arc_e0_ = 0;
    int arc_bound_ = 0;
};

// Inline: every tool move (most lines) passes here.
inline const ToolMove& Resolver::tool_move(const cmd::ToolMove& c) {
    const PlannerState& at = state_;
    ToolMove& mv = resolved_;
    if (c.hold_tip) {
        mv.tip = at.pose.tip;
    } else {
        // In the frame X Y Z are read in (the program frame, or the tilted plane's), and back.
        Eigen::Vector3d tip = at.pose.tip - at.offset;
        const WorkPlane* plane = c.plane ? &*c.plane : nullptr;
        if (plane) tip = plane->to_plane(tip);
        for (std::size_t i = 0; i < 3; ++i)
            if (c.xyz.given & (1u << i)) tip[Eigen::Index(i)] = c.xyz.relative ? tip[Eigen::Index(i)] + c.xyz.value[i] : c.xyz.value[i];
        mv.tip = (plane ? plane->to_program(tip) : tip) + at.offset;
    }
    // Under G43.4 the rotary words are programmed angles: the rest are the current ones.
    if (c.reads_angles) {
        angles_.programmed(at, mv.angles);
        for (cmd::JointBits b = c.angles_given; b != 0; b &= b - 1) {
            const std::size_t j = std::size_t(std::countr_zero(b));
            mv.angles[j] = c.angles_relative ? mv.angles[j] + c.angles[j] : c.angles[j];
        }
    }
    mv.axis = c.any_ijk ? c.axis : at.pose.axis;
    mv.commanded = c.commanded & joint_bits_;  // the machine's joints only
    mv.gcode = c.gcode;
    mv.column = c.column;
    mv.mode = c.mode;
    mv.any_xyz = c.any_xyz();
    mv.any_rotary = c.any_rotary();
    mv.any_ijk = c.any_ijk;
    mv.e = c.e;
    mv.f = c.f;
    mv.e_relative = c.e_relative;
    mv.e_position = at.e;
    mv.feed = c.feed;
    mv.inverse_time = c.inverse_time;
    return mv;
}

}  // namespace xlate5
