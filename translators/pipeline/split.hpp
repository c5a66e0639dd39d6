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
#include "translators/pipeline/split_check.hpp"
#include "translators/pipeline/split_points.hpp"

namespace xlate5 {

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

// The split of the last move: its pieces, parameter s at each piece's end, each end's joints as
// printed and as solved, and the start as printed.
class SplitPieces {
public:
    explicit SplitPieces(std::size_t joints) : joints_(joints) {}
    std::size_t count() const { return s_.size(); }
    const std::vector<double>& params() const { return s_; }
    const std::vector<double>& joints() const { return whole_ ? q1_printed_ : qs_; }  // pieces x joints
    const double* printed(std::size_t k) const { return whole_ ? q1_printed_.data() : &qs_[k * joints_]; }
    const double* exact(std::size_t k) const { return whole_ ? q1_exact_.data() : &qs_exact_[k * joints_]; }
    const std::vector<double>& start_printed() const { return q0_printed_; }
    // Where the move ends, as solved: its q1, or where a tool vector's continuous solution
    // arrived when the split found it on other joints (the other branch or another turn).
    const double* end_exact() const { return exact(count() - 1); }
    bool whole() const { return whole_; }  // one piece: the move's own q1 ends it

private:
    friend class Segmenter;  // which fills them
    std::size_t joints_;
    std::vector<double> s_, qs_;                 // the pieces, joints as printed
    std::vector<double> qs_exact_;               // the pieces' ends as solved
    // The move is one piece (s_ = {1}): its end is q1_printed_ as printed and q1_exact_ as
    // solved, and qs_, qs_exact_ are not filled.
    bool whole_ = false;
    std::vector<double> q0_printed_, q1_printed_;  // the move's ends as printed
    // The move's q1 as solved (the end asked for). Kept to the next split: a move that starts
    // there starts where the last one ended.
    std::vector<double> q1_exact_;
};

// The split to tolerance itself: where to cut (the march, each piece as long as the tolerance
// allows), with the tries near a pole (the other branch, a polar machine's continuous C); what a
// point is (SplitPoints) and whether a piece passes (PieceCheck) are their own units.
class Segmenter {
public:
    static constexpr int kCheckSamples = PieceCheck::kCheckSamples;

    explicit Segmenter(const Kinematics& kinematics);

    // Splits the move; on an error (a split point out of reach) the message says where along it.
    IkResult split(const PlannedMove& move);
    // The split of the last move.
    const SplitPieces& pieces() const { return pieces_; }
    // Degrees the rotaries turn along the pieces.
    double split_rotary_travel() const;

    // The split's points (poses, solves) and its test of a piece, for the motion stage's own use.
    const SplitPoints& points() const { return points_; }
    const PieceCheck& check() const { return check_; }

private:
    // The rest of split for a move that the bounds did not clear whole: sampled, and split if
    // it must be (split's usual move never gets here, and its code stays small).
    IkResult march(const PlannedMove& move, double tol);
    IkResult longest_piece(const PlannedMove& move, double tol, double sa, double step, double& ok_len);
    bool other_branch_passes(const PlannedMove& move, double sa, double sb, const std::vector<double>& qa, std::vector<double>& qb,
                             double tol);
    bool polar_continuous_passes(const PlannedMove& move, double sa, double sb, const std::vector<double>& qa, std::vector<double>& qb,
                                 double tol);

    const Kinematics& kin_;
    const Machine& machine_;
    const std::size_t joints_;  // the machine's joints (read where each move needs their number)
    SplitPoints points_;
    PieceCheck check_;
    PrintedRounding rounding_;
    SplitPieces pieces_;
    // The last move's end tip (which its q1, pieces_.q1_exact_, reaches).
    Eigen::Vector3d last_end_tip_ = Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
    // The march's tries, reused move after move (no allocation on the hot path): the try's target,
    // its end as solved, the longest passing end (printed: a, solved: ok_exact), the other
    // branch's try (b, alt_exact), and the pieces' ends.
    struct MarchScratch {
        SplitPoints::Target target;
        std::vector<double> exact_b, ok_exact, a, b, alt_exact, march_a, march_b;
    };
    MarchScratch m_;
};

}  // namespace xlate5
