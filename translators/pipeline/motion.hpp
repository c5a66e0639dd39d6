// SPDX-License-Identifier: GPL-3.0-or-later
// The motion stage, between the planner and the compensation stage: splits a tool-space move
// (already solved at both ends by the planner) until the firmware's joint-linear path stays within
// the tolerance of it, shares E among the pieces by tool-space length, and sets each piece's F so
// the tip moves at the programmed speed under the firmware's own feed rule. May call: kinematics,
// joint_limits (each split point stays inside the limits), the pole policy (pole_policy.hpp), the
// compensation stage, the emitter.
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
#include "translators/pipeline/pole_policy.hpp"
#include "translators/kinematics/kinematics.hpp"
#include "translators/machine/machine.hpp"

namespace xlate5 {

struct MoveSpec {
    int gcode = 1;
    OrientationMode mode = OrientationMode::Angles;  // how the move is interpolated in tool space
    const std::vector<double>* q0 = nullptr;         // start joints and pose
    Pose p0;
    const std::vector<double>* q1 = nullptr;         // end joints (solved) and pose
    Pose p1;
    // The position solve's own end, when it gave one: the split bounds the printed end from it
    // instead of an FK (used only when its joints are q1's).
    const Kinematics::SolvedEnd* end = nullptr;
    const std::vector<bool>* commanded = nullptr;
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
};

// A travel move that ended on another solution of its pose than the usual one.
enum class SolutionChange { None, Turns, Branch };

// What one move became, for the report and tests.
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
    int rezeros = 0;             // G92s the planner wrote after the move to re-zero a wound-up rotary
    std::uint64_t moves_written = 0;  // the emitter's count of move lines once the move was written (its output's place)
};

class MotionStage {
public:
    MotionStage(const Kinematics& kinematics, JointEmitter& emitter);

    // Splits, feeds and writes the move. On an error (a split point out of reach) nothing is
    // written and the message says where along the move.
    IkResult emit(const MoveSpec& move, std::string& out, MoveResult* result = nullptr);

    // Deviation of the firmware's joint-linear path from qa to qb from the programmed move,
    // between move parameters sa and sb: largest of `samples` interior points (tests use many).
    void piece_error(const MoveSpec& move, double sa, double sb, const double* qa, const double* qb, int samples,
                     double& tip, double& angle) const;

    // Where the last move ended: its end joints can differ from the ones asked for when a tool
    // vector's continuous solution arrives on the other branch or another turn.
    // (As solved: the printed ones are rounded to the dialect's decimals.) Null when they are the
    // end asked for (nearly always: then nothing is copied).
    const std::vector<double>* final_joints_moved() const { return final_moved_ ? &final_exact_ : nullptr; }

    // The orientation solutions of an axis the caller has already solved (the planner, for a move's
    // end): kept so the stage does not solve that axis again.
    void remember_solutions(const Kinematics::Solutions& solutions) const;

    // The split of the last move: parameter s at each piece's end and its joints.
    const std::vector<double>& split_params() const { return s_; }
    const std::vector<double>& split_joints() const { return whole_ ? q1_printed_ : qs_; }  // pieces x joints

private:
    // True when the firmware's path from qa to qb (move parameters sa to sb) is proved within
    // `tol` (mm) and the split's angle limit (chord_limit_) by kinematics' bound, without sampling it.
    bool bounded_within(const MoveSpec& move, double sa, double sb, const double* qa, const double* qb, double tol) const;
    // The same for the whole move under the angle form, from the machine's reach: no FK at all.
    bool reach_clears(const MoveSpec& move, double tol) const;
    // Splits made so far; the end's reach_shift reach_clears measured last, and in which split.
    std::uint64_t splits_ = 0;
    mutable std::uint64_t shift_split_ = std::numeric_limits<std::uint64_t>::max();  // (none: max + 1 is 0, no split's number)
    mutable double end_shift_ = 0;
    // piece_error's verdict against `tol` and the split's angle limit (sample_angle_), stopping at
    // the first point outside them. `middle_ratio`, when given, receives the error over its
    // tolerance when the verdict is no at the middle point (left as it is otherwise).
    bool piece_within(const MoveSpec& move, double sa, double sb, const double* qa, const double* qb, double tol,
                      double* middle_ratio = nullptr) const;
    IkResult emit_one(const MoveSpec& move, std::string& out, MoveResult* result);
    // Across a pole (pole_policy.hpp: cross): true, with the end on the other branch in `end`,
    // when the policy takes that way; else the continuous branch's split is kept for emit_one.
    bool cross_pole(const MoveSpec& move, std::vector<double>& end);
    // From a start held off its axis, when the continuous solution cannot be followed from it
    // (pole_policy.hpp: join): the first part, up to the policy's s1, in angle form with E shared
    // by tip length, then the rest as the usual vector move. Not ok when no s1 does that.
    IkResult join_from_held(const MoveSpec& move, std::string& out, MoveResult* result);
    std::vector<double> join_q_;
    double split_rotary_travel() const;
    IkResult solve_at(const MoveSpec& move, double s, const std::vector<double>& previous, std::vector<double>& q,
                      int branch = -1) const;
    // solve_at's steps under the vector form: the programmed pose at s and its orientation
    // solutions (the split's try at s and its tries of the other branch share them); the rotaries
    // from `previous` (the continuous solution, or `branch`'s); the linear joints and the limits.
    struct Target {
        Pose pose;
        Kinematics::Solutions solutions;
    };
    void target_at(const MoveSpec& move, double s, Target& target) const;
    // `chosen` receives which of target.solutions q's rotaries took, for place.
    IkResult orient_at(const MoveSpec& move, double s, const Target& target, const std::vector<double>& previous,
                       std::vector<double>& q, int branch, ChosenSolution& chosen) const;
    IkResult place(const Target& target, std::vector<double>& q, ChosenSolution chosen) const;
    // The rotary joints of a and b are the same to the bit.
    bool same_rotaries(const std::vector<double>& a, const std::vector<double>& b) const;
    Target target_;  // the split's current try
    IkResult split(const MoveSpec& move);
    // The rest of split for a move that the bounds did not clear whole: sampled, and split if
    // it must be (split's usual move never gets here, and its code stays small).
    IkResult march(const MoveSpec& move, double tol);
    Pose pose_at(const MoveSpec& move, double s) const;
    // An OutOfLimits result when the continuous solution at s (from `previous`) is outside a
    // rotary joint's limits.
    IkResult leaves_limits(const MoveSpec& move, double s, const std::vector<double>& previous) const;

    // The ends bounded_within met last (the end of one move is the start of the next).
    const Kinematics::PathEnd& path_end(const double* q) const {
        // The move's start as printed, when it is the last move's end and that end's slot still
        // holds it: that slot is the one the search would find (a slot is filled only when no
        // slot holds its joints, so no two hold the same).
        if (q == q0_printed_.data() && start_slot_ >= 0) return ends_[start_slot_].end;
        return find_end(q);
    }
    // path_end's search of the slots, and its FK (or near_end) when neither holds q.
    const Kinematics::PathEnd& find_end(const double* q) const;
    static constexpr std::size_t kPrintJoints = 8;
    struct CachedEnd {
        std::size_t n = 0;  // joints held (0: none)
        double q[kPrintJoints];
        Kinematics::PathEnd end;
    };
    mutable CachedEnd ends_[2];
    // The slots holding the ends of q0_printed_ and q1_printed_ as they are now (-1: not known;
    // the search finds them then).
    mutable int start_slot_ = -1, end_slot_ = -1;
    // The move's solved end while it is split (split() sets it when it holds for the move's q1):
    // path_end bounds q1_printed_ from it.
    const Kinematics::SolvedEnd* solved_end_ = nullptr;
    // The programmed axis's great circle of the move being split: its angle (an acos and a sine)
    // once per move, not once per try and sample point. Keyed by the two axes.
    const GreatArc& arc_of(const MoveSpec& mv) const;
    mutable GreatArc arc_{Eigen::Vector3d::UnitZ(), Eigen::Vector3d::UnitZ()};
    // The orientation solutions of the axes met last: one move's end axis is the next one's start.
    const Kinematics::Solutions& solutions_of(const Eigen::Vector3d& axis) const;
    struct CachedSolutions {
        bool valid = false;
        Eigen::Vector3d axis;
        Kinematics::Solutions solutions;
    };
    // The slot holding `axis` (bit for bit), or null; and the slot a new axis goes into.
    const CachedSolutions* cached_solutions(const Eigen::Vector3d& axis) const;
    const Kinematics::Solutions& cache_solutions(const Eigen::Vector3d& axis, Kinematics::Solutions solutions) const;
    mutable CachedSolutions solved_[2];
    mutable int solved_next_ = 0;
    mutable int ends_next_ = 0;
    const MoveSpec* split_for_ = nullptr;  // the move whose split s_, qs_ hold already (cross_pole made it)
    AngleLimit sample_angle_;  // the split's angle limit (the angle tolerance with its sampling margin)
    double chord_limit_;       // the bound's form of it: a tool axis within this chord is inside it (motion.cpp)

    const Kinematics& kin_;
    const Machine& machine_;
    const std::size_t joints_;  // the machine's joints (read where each move needs their number)
    LimitBox limits_;  // check_limits' verdict for the split's points (nearly all inside: no result built)
    CompensationStage compensation_;
    FeedRule feed_rule_;
    JointEmitter& emitter_;
    std::vector<double> s_, qs_;                 // the pieces, joints as printed
    std::vector<double> qs_exact_;               // the pieces' ends as solved
    // The move is one piece (s_ = {1}): its end is q1_printed_ as printed and the move's q1 as
    // solved, and qs_, qs_exact_ are not filled.
    bool whole_ = false;
    const double* piece_printed(std::size_t k) const { return whole_ ? q1_printed_.data() : &qs_[k * machine_.joints.size()]; }
    std::vector<double> q0_printed_, q1_printed_;  // the move's ends as printed
    // printed()'s usual case worked out once per joint (machines of up to kPrintJoints joints):
    // a value whose |value * print_scale_| is below print_below_ is rounded at once (to_units'
    // own arithmetic, its range tests passed by that one); any other goes through printed().
    // print_rotaries_: kinematics' rotaries (split's test whether they turn).
    double print_scale_[kPrintJoints] = {};
    double print_below_[kPrintJoints] = {};
    std::size_t print_rotaries_[kPrintJoints] = {};
    std::size_t print_rotary_count_ = 0;
    // split's start for a move whose joints have the stage's own size (n <= kPrintJoints): q1
    // rounded into q1_printed_ and copied into last_end_q_ in one pass; true when a rotary's
    // printed value differs from q0_printed_'s.
    bool print_end(const double* q1);
    // The last move's end: its joints as solved, and its tip (which they reach). Its joints as
    // printed are q1_printed_ until the next move's split.
    std::vector<double> last_end_q_;
    Eigen::Vector3d last_end_tip_ = Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
    std::vector<double> final_exact_, exact_b_, ok_exact_, cross_end_;
    bool final_moved_ = false;  // final_exact_ holds the last move's end (else it is the end asked for)
    PoleScratch cross_scratch_;
    double cross_angle_ = 0;  // the axis deviation of the last crossing found  // the last piece's end as solved (unrounded)
    // Scratch space reused move after move (no allocation on the hot path).
    std::vector<double> scratch_a_, scratch_b_, alt_exact_, lerp_, march_a_, march_b_;
    mutable std::vector<double> sample_;
    std::vector<double> piece_time_;  // minutes each piece of the last move takes
};

}  // namespace xlate5
