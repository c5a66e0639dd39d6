// SPDX-License-Identifier: GPL-3.0-or-later
// The planner stage, between the interpreter and the motion stage: turns a typed move into
// joint moves. It solves the end of each tool-space move (IK), chooses the solution (the
// continuous one, or for a travel move another solution of its pose inside the limits: the other
// branch or another turn; near a pole, over short moves, the turntable held within the angle
// tolerance), and is the stage that applies the joint limits. A tool move is planned in two
// steps with the motion stage between them, which translator.cpp calls in turn: plan() gives the
// PlannedMove the motion stage splits and writes, arrive() (and, for a move measured or that may
// re-zero, arrived()) takes the MotionOutcome (where the move really ended) and the report's
// figures, re-zeroes a wound-up turntable and moves the state on.
// Joint-space moves (G49), position changes (G92) and homing (G28) move its state on too. It
// writes no text: what the firmware is to be told (a joint move, a G92) it returns as a value,
// which translator.cpp hands through the compensation stage to the emitter.
// May call: kinematics, joint_limits, the pole policy and the report's move log. Never the motion
// stage, the compensation stage or the emitter.
#pragma once
#include <algorithm>
#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "translators/pipeline/commands.hpp"
#include "translators/pipeline/joint_limits.hpp"
#include "translators/kinematics/kinematics.hpp"
#include "translators/machine/machine.hpp"
#include "translators/pipeline/planned_move.hpp"
#include "translators/pipeline/pole_policy.hpp"

namespace xlate5 {

class MoveLog;

// Under G43.4 the programmed angles are carried onto the joints through q = sign * a + shift
// per rotary (in rotary_joints() order): identity until a travel move unwinds onto another
// turn (shift 360 k) or, where the machine has the flip, the other branch (+180, -1).
struct AngleImage {
    double sign[2] = {1, 1};
    double shift[2] = {0, 0};
    bool operator==(const AngleImage&) const = default;
};

// What the planner keeps between moves: where the machine is. A plain value: the look-back
// copies it before a line that may travel (lookback.hpp).
struct PlannerState {
    std::vector<double> q;   // joint values the firmware will be at
    Pose pose;               // tip and tool axis in the part frame
    // The program frame's origin in the part frame (G92 X Y Z under tool-centre-point control).
    Eigen::Vector3d offset = Eigen::Vector3d::Zero();
    double e = 0;            // the extruder's absolute position (for sharing an absolute E among pieces)
    bool tip_known = false;  // has the program placed the tip since start or G28?
    AngleImage image;        // G43.4: programmed angles -> joints
    // Per rotary (rotary_joints() order): the whole turns re-zeros took off the joint since the
    // program last set it (G92, G28), in degrees. The program's angles go on without them.
    double rezeroed[2] = {0, 0};
    // With a report: the least rotary travel to each solution of the last move's end axis, by
    // dynamic programming over the moves so far (bound_rotary_travel, planner.cpp). Here so that a
    // look-back replay takes it back with the rest.
    struct RotaryBound {
        int n = 0;  // solutions held (0: not started)
        double best[2] = {0, 0}, c[2] = {0, 0}, b[2] = {0, 0};
        double slack_c = 0, slack_b = 0;
    } bound;
};

// One input line's dealings with the look-back: what it asks of the line's moves, and what they
// did. An argument of every move, never a member left set for the next call.
struct LineRun {
    std::uint64_t line_no = 0;
    int end_candidate = -1;          // in: the line's first travel move ends on this other solution (a replay)
    bool travels = false;            // out: the line made a tool-space travel move
    bool hit_limit = false;          // out: it failed on a joint limit
    bool linear_limit = false;       // out: ... of a linear joint (the part is placed out of reach)
    bool absent_limit = false;       // out: ... of a joint the machine does not have (the pose is out of reach)
    bool at_pole = false;            // out: it failed at a pole (no way within the tolerance there)
    bool candidate_missing = false;  // out: there is no solution end_candidate
    PoleChoices pole;                // in and out: the window's branch choices near a pole (a replay flips some)
};

// A tool-space move as the interpreter read it (G0/G1 under G43.4/G43.5, or an arc's chord).
struct ToolMove {
    int gcode = 1;
    std::uint32_t column = 1;                    // of the command, for errors
    OrientationMode mode = OrientationMode::Angles;
    bool any_xyz = false;
    Eigen::Vector3d tip = Eigen::Vector3d::Zero();   // part frame (the current tip when no X Y Z)
    bool any_rotary = false;
    Joints angles;  // programmed angle per joint (rotaries): under G43.4 the words, or the current ones; not filled under G43.5 (tool-vector mode), where nothing reads them
    bool any_ijk = false;
    Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();  // G43.5: the tool axis, unit (when any_ijk)
    JointBits commanded = 0;  // joints the line names (directly or through the tip), the machine's only
    std::optional<PassedNumber> e, f;
    bool e_relative = false;
    double e_position = 0;   // absolute E before the move
    double feed = 0;         // programmed feed, mm/min
    bool inverse_time = false;
};

// Programmed angles <-> joints through an AngleImage, per rotary (`rot`: the kinematics'
// rotary_joints(), in that order).
struct AngleMap {
    const std::vector<int>& rot;
    void map(const AngleImage& image, const Joints& a, std::vector<double>& q) const;
    void unmap(const AngleImage& image, const std::vector<double>& q, Joints& a) const;
    // The image with no other turn or branch chosen: identity, but for the turns re-zeros took off.
    void plain(PlannerState& s) const;
    void forget_rezeros(PlannerState& s, JointBits which) const;  // joints the program has just set
    // The programmed angles (G43.4) of the joints `s` is at, per joint: the rotaries' through the
    // image (the plain image gives the joints themselves: (q - 0) * 1 is q, bit for bit). Only the
    // rotaries' are read (map), so only they are written.
    void programmed(const PlannerState& s, Joints& a) const {
        if (!(s.image == AngleImage{})) return unmap(s.image, s.q, a);
        for (const int j : rot) a[std::size_t(j)] = s.q[std::size_t(j)];
    }
};

// Another end a travel move may take (end_candidates, planner.cpp): its joints and, under G43.4, the
// image of the programmed angles that gives them.
struct EndCandidate {
    std::vector<double> q;
    AngleImage image;
};

// A tool move as the planner planned it: the PlannedMove the motion stage takes, and what the
// planner chose on the way, which its arrival reads (Planner::arrive). The planner's own buffer,
// made in place move after move (the joint arrays are set once).
struct MovePlan {
    PlannedMove move;
    std::uint32_t column = 1;  // of the command, for errors
    bool prints = false;       // the move extrudes
    bool travel = false;       // a tool-space move that does not extrude: it may end on another solution
    bool unwind = false;       // it ends on another solution than the continuous one, in angle form
    bool passage = false;      // near a pole, a passage (pole_policy.hpp), in angle form
    bool places_tip = false;   // it gives X Y Z: the program has placed the tip once it arrives
    bool measure = false;      // the report measures it (MoveResult)
    double passage_angle = 0;  // the passage's largest axis deviation, as checked
    SolutionChange change = SolutionChange::None;  // an unwind's kind, for the report
};

class Planner {
public:
    // `log` (may be null) receives every measured tool-space move for the report.
    Planner(const Kinematics& kinematics, PlannerState& state, MoveLog* log);

    // A tool move, first step: its end solved and its solution chosen, as the move the motion
    // stage is to write (MovePlan::move), valid until the next plan(). Throws LineError(column,
    // cause) when its end cannot be reached; `run` says whether the move travels or hit a limit.
    MovePlan& plan(const ToolMove& move, LineRun& run);
    // The motion stage could not write a planned move: whether the planner has it written again
    // another way (the plan is then changed). The continuous path of a travel move leaves the
    // limits, though its end (the solution nearest the start inside them) does not: it turns
    // there in angle form instead.
    static bool retry_in_angle_form(MovePlan& plan, const MotionOutcome& outcome) {
        if (outcome.ok() || outcome.result.status != IkStatus::OutOfLimits || !plan.travel || plan.unwind ||
            plan.move.mode != OrientationMode::Vector)
            return false;
        plan.move.mode = OrientationMode::Angles;
        plan.unwind = true;
        return true;
    }
    // A tool move, last step: the motion stage's outcome of the plan taken on (the plan last
    // made: a plan() and its arrive() are made in turn, move after move). Throws LineError
    // when it failed (`run` says whether on a limit or at a pole); else the machine is where the
    // move ended (the next move starts there). Returns true when the move has more to settle
    // (it is `measured` for the report, or may re-zero a wound-up rotary): arrived() must then
    // be called, and moves the state on; false (most printing moves): done.
    bool arrive(const MovePlan& plan, const MotionOutcome& outcome, bool measured, LineRun& run);
    // The rest of a move arrive() left to settle: a wound-up rotary is re-zeroed and, when the
    // plan is measured, `measured` (the motion stage's figures, its moves_written set) is
    // completed and logged for the report. Returns the re-zeros' G92s to write after the move
    // (valid until the next arrive()), usually none.
    std::span<const SetJoints> arrived(const MovePlan& plan, MoveResult* measured, LineRun& run);
    // A tool move's E, as a whole (its pieces apart): the extruder's position after it.
    void extruded(const std::optional<PassedNumber>& e, bool relative) {
        if (e) state_.e = relative ? state_.e + e->value : e->value;
    }
    // G49: the joints named move (checked against the limits); returns the move to write (its E
    // is not taken on: extruded() after it is written).
    JointStep joint_move(const cmd::JointMove& move);
    // G92: the joints named (the pose follows from them when the command says so), the program
    // frame, E; returns what the firmware is to be told: the joints and E.
    SetJoints set_position(const cmd::SetPosition& set);
    // G28 for the joints named: they are at their home values, the program frame is the part's.
    // The firmware's position is then not exactly known (the emitter's to be told).
    void home(const cmd::Home& home);
    // A move passed on as written (joint-space arcs), or the firmware's report: the joints end at
    // `q`, a position the emitter is to be told is not exactly known.
    void moved_to(const cmd::MovedTo& to);
    void moved_to(const std::vector<double>& q);
    // A mode switch: the programmed angles mean the joints as they are (but for re-zeros).
    void new_mode() { angle_map_.plain(state_); }

private:
    // arrive's steps: a move the motion stage could not write refused (throws, planner.cpp), and
    // the state moved on to the move's end.
    [[noreturn]] static void refused(const MovePlan& plan, const IkResult& result, LineRun& run);
    void move_on(const MovePlan& plan);
    // plan's steps (planner.cpp).
    IkResult solve_end(const ToolMove& mv, Pose& next);
    bool other_end(const ToolMove& mv, const Pose& next, bool travel, IkResult& r, LineRun& run, SolutionChange& change);
    int rezero();

    const Kinematics& kin_;
    LimitBox limits_;  // the end of every move is checked against it
    PlannerState& state_;
    MoveLog* log_;
    // The end of the move being solved; from plan() to arrive() the planned move's q1, which
    // arrive() takes on unless the motion stage ended the move elsewhere.
    std::vector<double> q_next_;
    std::vector<EndCandidate> candidates_;
    std::vector<double> pole_q_;  // scratch: a passage's end
    PoleHold pole_hold_;
    Kinematics::Solutions end_solutions_;  // of the move's end axis (G43.5 with I J K)
    // The plan handed out (plan()); its move's `end` is filled by the end's position solve.
    MovePlan plan_;
    AngleMap angle_map_;
    std::array<SetJoints, 2> rezeros_;  // arrive()'s G92s, one per rotary re-zeroed
};

// Inline: every tool move passes here, and most need none of the report's figures or re-zeros.
inline bool Planner::arrive(const MovePlan& p, const MotionOutcome& outcome, bool measured, LineRun& run) {
    if (!outcome.ok()) refused(p, outcome.result, run);
    // Where the move ended: its own q1 (which plan() left in q_next_), or where the split of its
    // last part arrived.
    if (outcome.ended) std::copy(outcome.ended->begin(), outcome.ended->begin() + std::ptrdiff_t(q_next_.size()), q_next_.begin());
    if (measured || log_ || !p.prints) return true;
    move_on(p);
    return false;
}

inline void Planner::move_on(const MovePlan& p) {
    PlannerState& s = state_;
    s.q.swap(q_next_);
    s.pose = p.move.p1;
    s.tip_known = s.tip_known || p.places_tip;
}

}  // namespace xlate5
