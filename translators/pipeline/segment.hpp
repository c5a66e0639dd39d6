// SPDX-License-Identifier: GPL-3.0-or-later
// The split to tolerance, between the planner and the rest of the motion stage: cuts a
// tool-space move (already solved at both ends) into pieces until the firmware's joint-linear
// path stays within the tolerance of the programmed one (tip, and tool axis under the vector
// form), each piece's end solved from the one before so the solution stays continuous, each
// checked by kinematics' path bound first and by samples where that does not clear it. The
// joints are measured as printed: the split checks the path the firmware will really take.
// May call: kinematics, joint_limits (each split point stays inside the limits), the emitter's
// rounding.
#pragma once
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "translators/kinematics/great_arc.hpp"
#include "translators/kinematics/kinematics.hpp"
#include "translators/machine/machine.hpp"
#include "translators/pipeline/joint_limits.hpp"
#include "translators/pipeline/planned_move.hpp"

namespace xlate5 {

// The orientation solutions of the axes met last (one move's end axis is the next one's start),
// keyed by the axis's bits: a pure function of them, so a hit gives what a solve would.
class SolutionCache {
public:
    explicit SolutionCache(const Kinematics& kinematics) : kin_(kinematics) {}
    const Kinematics::Solutions& of(const Eigen::Vector3d& axis) const;
    // Solutions the caller has already solved, remembered without a search: a slot holding the
    // same axis holds the same solutions, so a second copy changes no answer.
    void remember(const Kinematics::Solutions& solutions) const { store(solutions.axis, solutions); }

private:
    struct Slot {
        bool valid = false;
        Eigen::Vector3d axis;
        Kinematics::Solutions solutions;
    };
    const Kinematics::Solutions& store(const Eigen::Vector3d& axis, Kinematics::Solutions solutions) const;
    const Kinematics& kin_;
    mutable Slot slots_[2];
    mutable int next_ = 0;
};

// The joints as the firmware will be given them, rounded to each joint's printed decimals with
// the usual case worked out once per joint (machines of up to kMaxJoints joints): a value whose
// |value * scale| is below `below` is rounded at once (to_units' own arithmetic, its range tests
// passed by that one); any other goes through printed_value.
class PrintedRounding {
public:
    PrintedRounding(const Kinematics& kinematics);
    // q1 rounded into `to` and copied into `exact` in one pass, for a machine of at most
    // kMaxJoints joints; true when a rotary's printed value differs from `from`'s.
    bool round_end(const double* q1, double* to, double* exact, const double* from) const;

private:
    const Machine& machine_;
    std::size_t joints_;
    double scale_[kMaxJoints] = {};
    double below_[kMaxJoints] = {};
    std::size_t rotaries_[kMaxJoints] = {};  // kinematics' rotaries
    std::size_t rotary_count_ = 0;
};

// The path ends the split met last (the end of one move is the start of the next): two slots of
// joints with their PathEnd, and which of them hold the move's start and end as printed.
class EndCache {
public:
    explicit EndCache(const Kinematics& kinematics) : kin_(kinematics), joints_(kinematics.machine().joints.size()) {}
    // The PathEnd at q: `start` when q is the move's start as printed, `end` when it is its end
    // as printed, bounded from `solved` (the position solve's own end) where that holds for it.
    const Kinematics::PathEnd& at(const double* q, bool start, bool end, const Kinematics::SolvedEnd* solved) const {
        // The move's start, when it is the last move's end and that end's slot still holds it:
        // that slot is the one the search would find (a slot is filled only when no slot holds
        // its joints, so no two hold the same).
        if (start && start_slot_ >= 0) return slots_[start_slot_].end;
        return find(q, end, solved);
    }
    // A new move: its start is the last one's end (whose slot is known), or not.
    void next_move(bool from_last) {
        start_slot_ = from_last ? end_slot_ : -1;
        end_slot_ = -1;
    }

private:
    // The search of the slots, and the FK (or near_end) when neither holds q.
    const Kinematics::PathEnd& find(const double* q, bool is_end, const Kinematics::SolvedEnd* solved) const;
    struct Slot {
        std::size_t n = 0;  // joints held (0: none)
        double q[kMaxJoints];
        Kinematics::PathEnd end;
    };
    const Kinematics& kin_;
    std::size_t joints_;
    mutable Slot slots_[2];
    mutable int next_ = 0;
    // The slots holding the move's start and end as printed (-1: not known; the search finds them).
    mutable int start_slot_ = -1, end_slot_ = -1;
};

class Segmenter {
public:
    static constexpr int kCheckSamples = 7;  // interior points checked per piece (see piece_error)

    explicit Segmenter(const Kinematics& kinematics);

    // Splits the move; on an error (a split point out of reach) the message says where along it.
    IkResult split(const MoveSpec& move);

    // The split of the last move: its pieces, parameter s at each piece's end, each end's joints
    // as printed and as solved, and the start as printed.
    std::size_t pieces() const { return s_.size(); }
    const std::vector<double>& split_params() const { return s_; }
    const std::vector<double>& split_joints() const { return whole_ ? q1_printed_ : qs_; }  // pieces x joints
    const double* piece_printed(std::size_t k) const { return whole_ ? q1_printed_.data() : &qs_[k * machine_.joints.size()]; }
    const double* piece_exact(std::size_t k, const MoveSpec& move) const {
        return whole_ ? move.q1->data() : &qs_exact_[k * machine_.joints.size()];
    }
    const std::vector<double>& start_printed() const { return q0_printed_; }
    // Degrees the rotaries turn along the pieces.
    double split_rotary_travel() const;

    // Deviation of the firmware's joint-linear path from qa to qb from the programmed move,
    // between move parameters sa and sb: largest of `samples` interior points (tests use many).
    void piece_error(const MoveSpec& move, double sa, double sb, const double* qa, const double* qb, int samples,
                     double& tip, double& angle) const;

    // Where the last move ended, when a tool vector's continuous solution arrived on other joints
    // than the ones asked for (the other branch or another turn), as solved; null otherwise.
    const std::vector<double>* final_joints_moved() const { return final_moved_ ? &final_exact_ : nullptr; }
    // The last move ended at `q` (a way the pole policy chose).
    void ended_at(const std::vector<double>& q) {
        final_exact_ = q;
        final_moved_ = true;
    }

    // The orientation solutions of an axis (remembered: one move's end is the next one's start),
    // and of an axis the caller has already solved, remembered for it.
    const Kinematics::Solutions& solutions_of(const Eigen::Vector3d& axis) const { return solutions_.of(axis); }
    void remember_solutions(const Kinematics::Solutions& solutions) const { solutions_.remember(solutions); }
    // The programmed axis's great circle, and the programmed pose at move parameter s.
    const GreatArc& arc_of(const MoveSpec& mv) const;
    Pose pose_at(const MoveSpec& move, double s) const;
    IkResult solve_at(const MoveSpec& move, double s, const std::vector<double>& previous, std::vector<double>& q,
                      int branch = -1) const;

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
    // The rest of split for a move that the bounds did not clear whole: sampled, and split if
    // it must be (split's usual move never gets here, and its code stays small).
    IkResult march(const MoveSpec& move, double tol);
    IkResult longest_piece(const MoveSpec& move, double tol, double sa, double step, double& ok_len);
    bool other_branch_passes(const MoveSpec& move, double sa, double sb, const std::vector<double>& qa, std::vector<double>& qb,
                             double tol);
    bool polar_continuous_passes(const MoveSpec& move, double sa, double sb, const std::vector<double>& qa, std::vector<double>& qb,
                                 double tol);
    // An OutOfLimits result when the continuous solution at s (from `previous`) is outside a
    // rotary joint's limits.
    IkResult leaves_limits(const MoveSpec& move, double s, const std::vector<double>& previous) const;

    // The ends bounded_within met last (the end of one move is the start of the next).
    const Kinematics::PathEnd& path_end(const double* q) const {
        return ends_.at(q, q == q0_printed_.data(), q == q1_printed_.data(), solved_end_);
    }
    EndCache ends_;
    // The move's solved end while it is split (split() sets it when it holds for the move's q1):
    // path_end bounds q1_printed_ from it.
    const Kinematics::SolvedEnd* solved_end_ = nullptr;
    // The programmed axis's great circle of the move being split: its angle (an acos and a sine)
    // once per move, not once per try and sample point. Keyed by the two axes.
    mutable GreatArc arc_{Eigen::Vector3d::UnitZ(), Eigen::Vector3d::UnitZ()};
    SolutionCache solutions_;
    AngleLimit sample_angle_;  // the split's angle limit (the angle tolerance with its sampling margin)
    double chord_limit_;       // the bound's form of it: a tool axis within this chord is inside it (segment.cpp)

    const Kinematics& kin_;
    const Machine& machine_;
    const std::size_t joints_;  // the machine's joints (read where each move needs their number)
    LimitBox limits_;  // check_limits' verdict for the split's points (nearly all inside: no result built)
    std::vector<double> s_, qs_;                 // the pieces, joints as printed
    std::vector<double> qs_exact_;               // the pieces' ends as solved
    // The move is one piece (s_ = {1}): its end is q1_printed_ as printed and the move's q1 as
    // solved, and qs_, qs_exact_ are not filled.
    bool whole_ = false;
    std::vector<double> q0_printed_, q1_printed_;  // the move's ends as printed
    PrintedRounding rounding_;
    // The last move's end: its joints as solved, and its tip (which they reach). Its joints as
    // printed are q1_printed_ until the next move's split.
    std::vector<double> last_end_q_;
    Eigen::Vector3d last_end_tip_ = Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
    std::vector<double> final_exact_, exact_b_, ok_exact_;
    bool final_moved_ = false;  // final_exact_ holds the last move's end (else it is the end asked for)
    // Scratch space reused move after move (no allocation on the hot path).
    std::vector<double> scratch_a_, scratch_b_, alt_exact_, lerp_, march_a_, march_b_;
    mutable std::vector<double> sample_;
};

}  // namespace xlate5
