// SPDX-License-Identifier: GPL-3.0-or-later
// The split's test of one piece: whether the firmware's joint-linear path between two joint sets
// (as printed) stays within the tolerance of the programmed move between their move parameters,
// tip and (vector form) tool axis. Kinematics' path bound first, which usually decides without
// any FK; samples where it does not. For the split to tolerance (split.hpp). May call:
// kinematics, the split's points (the programmed axis's arc).
#pragma once
#include <cstdint>
#include <limits>
#include <vector>

#include "translators/kinematics/great_arc.hpp"
#include "translators/kinematics/kinematics.hpp"
#include "translators/pipeline/planned_move.hpp"
#include "translators/pipeline/split_points.hpp"

namespace xlate5 {

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

class PieceCheck {
public:
    static constexpr int kCheckSamples = 7;  // interior points checked per piece (see piece_error)

    // `angle_degrees`: the split's angle limit (the angle tolerance with its sampling margin).
    PieceCheck(const Kinematics& kinematics, const SplitPoints& points, double angle_degrees);

    // A new move (every split): its start is the last one's end, or not.
    void next_move(bool from_last) {
        ++splits_;
        ends_.next_move(from_last);
    }
    // The move's ends as printed (the pieces' first start and last end: their PathEnds are
    // cached across moves) and its solved end (null, or the position solve's end for q1: the
    // printed end is bounded from it), for the move being split.
    void set_ends(const double* start, const double* end, const Kinematics::SolvedEnd* solved) {
        start_ = start, end_ = end, solved_end_ = solved;
    }
    double angle_limit() const { return sample_angle_.degrees(); }

    // Deviation of the firmware's joint-linear path from qa to qb from the programmed move,
    // between move parameters sa and sb: largest of `samples` interior points (tests use many).
    void piece_error(const PlannedMove& move, double sa, double sb, const double* qa, const double* qb, int samples,
                     double& tip, double& angle) const;
    // piece_error's verdict against `tol` and the split's angle limit (sample_angle_), stopping at
    // the first point outside them. `middle_ratio`, when given, receives the error over its
    // tolerance when the verdict is no at the middle point (left as it is otherwise).
    bool piece_within(const PlannedMove& move, double sa, double sb, const double* qa, const double* qb, double tol,
                      double* middle_ratio = nullptr) const;
    // True when the firmware's path from qa to qb (move parameters sa to sb) is proved within
    // `tol` (mm) and the split's angle limit (chord_limit_) by kinematics' bound, without sampling it.
    bool bounded_within(const PlannedMove& move, double sa, double sb, const double* qa, const double* qb, double tol) const;
    // The same for the whole move (set_ends) under the angle form, from the machine's reach: no FK at all.
    bool reach_clears(const PlannedMove& move, double tol) const;

private:
    // The ends bounded_within met last (the end of one move is the start of the next).
    const Kinematics::PathEnd& path_end(const double* q) const { return ends_.at(q, q == start_, q == end_, solved_end_); }

    const Kinematics& kin_;
    const SplitPoints& points_;
    std::size_t joints_;
    AngleLimit sample_angle_;  // the split's angle limit
    double chord_limit_;       // the bound's form of it: a tool axis within this chord is inside it (split_check.cpp)
    EndCache ends_;
    const double* start_ = nullptr;
    const double* end_ = nullptr;
    const Kinematics::SolvedEnd* solved_end_ = nullptr;
    // Splits made so far; the end's reach_shift reach_clears measured last, and in which split.
    std::uint64_t splits_ = 0;
    mutable std::uint64_t shift_split_ = std::numeric_limits<std::uint64_t>::max();  // (none: max + 1 is 0, no split's number)
    mutable double end_shift_ = 0;
    mutable std::vector<double> sample_;  // scratch
};

}  // namespace xlate5
