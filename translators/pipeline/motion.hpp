// SPDX-License-Identifier: GPL-3.0-or-later
// The motion stage, between the planner and the compensation stage: takes a PlannedMove (a
// tool-space move already solved at both ends by the planner), has it split to tolerance
// (split.hpp) or made one of the pole policy's ways (pole_policy.hpp), shares E among the pieces
// by tool-space length, sets each piece's F by the firmware's feed rule (feed_rules.hpp), hands
// the pieces, measured errors taken off (compensation), to the emitter, and returns a
// MotionOutcome: whether the move was written and where it ended. It never sees the planner:
// translator.cpp hands it the planner's moves and hands its outcomes back to the planner.
// May call: kinematics, the split, the pole policy, the feed rule, the compensation stage, the
// emitter.
#pragma once
#include <cstdint>
#include <optional>
#include <limits>
#include <string>
#include <vector>

#include "translators/pipeline/compensation.hpp"
#include "translators/pipeline/emitter.hpp"
#include "translators/pipeline/feed_rules.hpp"
#include "translators/kinematics/great_arc.hpp"
#include "translators/pipeline/joint_limits.hpp"
#include "translators/pipeline/planned_move.hpp"
#include "translators/pipeline/pole_policy.hpp"
#include "translators/pipeline/split.hpp"
#include "translators/kinematics/kinematics.hpp"
#include "translators/machine/machine.hpp"

namespace xlate5 {

class MotionStage {
public:
    MotionStage(const Kinematics& kinematics, JointEmitter& emitter);

    // Splits, feeds and writes the move; `result`, when given, receives the report's figures of
    // its pieces (MoveResult: the planner adds its own before the log takes them).
    MotionOutcome emit(const PlannedMove& move, std::string& out, MoveResult* result = nullptr);

    // Deviation of the firmware's joint-linear path from qa to qb from the programmed move,
    // between move parameters sa and sb: largest of `samples` interior points (tests use many).
    void piece_error(const PlannedMove& move, double sa, double sb, const double* qa, const double* qb, int samples,
                     double& tip, double& angle) const {
        segment_.check().piece_error(move, sa, sb, qa, qb, samples, tip, angle);
    }

    // The split of the last move: parameter s at each piece's end and its joints.
    const std::vector<double>& split_params() const { return segment_.pieces().params(); }
    const std::vector<double>& split_joints() const { return segment_.pieces().joints(); }  // pieces x joints

private:
    IkResult emit_move(const PlannedMove& move, std::string& out, MoveResult* result);
    bool leave_pole(const PlannedMove& move, std::string& out, MoveResult* result, IkResult& r);
    IkResult emit_one(const PlannedMove& move, std::string& out, MoveResult* result);
    // Across a pole (pole_policy.hpp: cross): true, with the end on the other branch in `end`,
    // when the policy takes that way; else the continuous branch's split is kept for emit_one.
    bool cross_pole(const PlannedMove& move, std::vector<double>& end);
    // From a start held off its axis, when the continuous solution cannot be followed from it
    // (pole_policy.hpp: join): the first part, up to the policy's s1, in angle form with E shared
    // by tip length, then the rest as the usual vector move. Not ok when no s1 does that.
    IkResult join_from_held(const PlannedMove& move, std::string& out, MoveResult* result);
    // A passage with a half turn in place (pole_policy.hpp: turn): to the turn's joints, the turn
    // (no E, the tip held), then to the end, each part in angle form, E shared by tip length.
    IkResult turn_in_place(const PlannedMove& move, std::string& out, MoveResult* result);
    // The move's start joints as a joint vector, for the pole policy (start_q_).
    const std::vector<double>& start_of(const PlannedMove& move) {
        start_q_.assign(move.q0.begin(), move.q0.begin() + std::ptrdiff_t(joints_));
        return start_q_;
    }
    // The report's figures of the pieces just written.
    void measure(const PlannedMove& move, MoveResult& result) const;

    const Kinematics& kin_;
    const Machine& machine_;
    const std::size_t joints_;  // the machine's joints (read where each move needs their number)
    Segmenter segment_;
    FeedRule feed_rule_;
    CompensationStage compensation_;
    JointEmitter& emitter_;
    const PlannedMove* split_for_ = nullptr;  // the move whose split segment_ holds already (cross_pole made it)
    PoleScratch cross_scratch_;
    std::vector<double> cross_end_, join_q_, probe_q_;  // the ends the pole policy chose; its probe
    std::vector<double> start_q_;  // see start_of
    double cross_angle_ = 0;  // the axis deviation of the last crossing found
    bool crossed_ = false;    // the move being written crossed the pole (its end is cross_end_)
    std::vector<double> piece_time_;  // minutes each piece of the last move takes
};

}  // namespace xlate5
