// SPDX-License-Identifier: GPL-3.0-or-later
// The pole policy, in one place: what xlate5 does where the tool axis nears a pole of a machine
// with two rotaries (the axis along the first rotary, which then turns it no more).
// - hold (the planner, PoleHold): within the pole region the end of a short move may be held off
//   its programmed axis, within a budget, so the turntable need not follow the axis's azimuth;
// - passage (the planner, PoleHold): from a held start the rotaries turn linearly to the end;
// - cross (the motion stage, pole_crossing): a move may reach its end on the other branch with
//   the rotaries turning linearly, when that turns them clearly less;
// - join (the motion stage, pole_join): from a held start that the continuous solution cannot
//   follow, a first part turns linearly onto it;
// - re-index (the motion stage, pole_reindex): leaving a pole, a free joint turns first, in place;
// - turn (the planner, PoleHold, as a last resort): a branch choice the look-back flipped whose
//   passage cannot be made in one joint-linear turn is made in three: to the move's closest
//   approach to the pole, a half turn there in place onto the other branch, then on to the end.
// Every way keeps the tool axis within the angle tolerance of its programmed arc (checked).
// May call: kinematics, joint_limits.
#pragma once
#include <cstdint>
#include <functional>
#include <vector>

#include <Eigen/Core>

#include "translators/kinematics/great_arc.hpp"
#include "translators/kinematics/kinematics.hpp"
#include "translators/machine/machine.hpp"
#include "translators/pipeline/planned_move.hpp"

namespace xlate5 {

// Near a pole (the tool axis along the turntable's axis, which then turns it no more), the
// turntable's angle matters less the nearer the axis is: at a tilt t from the pole, turning it by
// d moves the tool axis by asin(sin t sin d). So there it need not follow the axis's azimuth,
// which swings round fast however slowly the axis moves past (a half turn for a passage that
// misses the pole by a hair, over however many short moves). Within kPoleRegion angle tolerances
// of the pole the end of each short move (turning the tool axis by less than the tolerance: a
// longer one ends exactly on its programmed axis) may leave that axis by a budget: kPoleHold of the
// tolerance up to that tilt (any turntable angle will do: it is held), falling linearly to zero
// at the region's edge, where the ends are exact again. The other half of the tolerance is left
// for the joint-linear turn between the ends, which is checked on kPoleSamples points.
// (Affouard et al.'s singularity cone with Grandguillaume et al.'s patching of C, as Isa, Koc
// 2018, sec. 4.6 uses them; here the cone is the angle tolerance and the patch bounded by it.)
constexpr double kPoleRegion = 2.0;
constexpr double kPoleHold = 0.5;
constexpr int kPoleSamples = 64;
constexpr double kPoleMargin = 0.97;  // as the motion stage's sampling margin
constexpr double kPoleSlack = 1e-9;   // degrees: rounding in pole_passage's two computations of the gap


// Another way than the continuous branch's is taken only when it turns the rotaries by this many
// degrees less.
constexpr double kPoleClearlyLess = 1.0;
constexpr double kPoleWideTurns = 4.0;

// The branch choices the hold made near a pole (held_end: the exact angles of more than one
// solution within reach, clearly apart), counted across a look-back window. Each takes the
// nearest angle unless the look-back asks for the other one there: which branch a printed loop
// needs where it passes a bounded turning joint's pole can depend on where the loop goes long
// after (lookback.cpp).
struct PoleChoices {
    static constexpr int kMaxFlips = 4;
    int seen = 0;                  // choices made so far (in: before the line; out: after it)
    int flips[kMaxFlips] = {};     // choices to take the other way (indices into seen's count)
    int n_flips = 0;
    // A flipped choice whose passage one joint-linear turn cannot make may turn the head in place
    // where the move passes nearest the pole (PoleTurn): the look-back allows it only after every
    // replay without it has failed, so a half turn inside a printing move is taken only where no
    // other way it tries keeps the path within the limits.
    bool turns = false;
    // After those too have failed: a move turning the tool axis by up to kPoleWideTurns angle
    // tolerances may be held near the pole as well (a loop drawn with few, long moves: where its
    // end lies nearest the pole the budget lets the turning joint stay back), the look-back's
    // last pass.
    bool wide = false;
    bool next_flipped() {
        const int i = seen++;
        for (int k = 0; k < n_flips; ++k)
            if (flips[k] == i) return true;
        return false;
    }
};

class PoleHold {
public:
    explicit PoleHold(const Kinematics& kinematics);

    // The machine has a pole this policy handles (two rotaries, the flip, splitting on).
    bool applies() const { return checks_; }
    // The pole: the tool axis with the tilting rotary at 0.
    const Eigen::Vector3d& pole() const { return pole_; }

    // Near a pole, across moves: the end of a tool-vector move from `from` (joints q0) to `to`
    // (usual end: `usual`) with the turntable turned no more than the angle tolerance needs.
    // Returns true, with the end joints in `q` (linear joints solved) and, with `need_worst`, the
    // worst axis deviation of the joint-linear turn in `worst`, when the move is to be made that
    // way (rotaries linear, angle form). `start_held` says whether the start was off its axis.
    // `at_end`, when given, holds the orientation solutions of to.axis.
    bool passage(const std::vector<double>& q0, const std::vector<double>& usual, const Pose& from, const Pose& to,
                 const Kinematics::Solutions* at_end, std::vector<double>& q, double& worst, bool need_worst,
                 bool& start_held, PoleChoices& choices);
    // The last passage's turn in place (valid only when passage made it so).
    const PoleTurn& turn() const { return turn_; }
    // A move's end as solved, whose axis the next move's start asks for.
    void remember_axis(const std::vector<double>& q, const Eigen::Vector3d& axis);

private:
    bool hold(const std::vector<double>& q0, const std::vector<double>& usual, const Pose& from, const Pose& to,
              const Kinematics::Solutions* at_end, std::vector<double>& q, double& worst, bool need_worst, bool start_exact,
              bool hold_end, PoleChoices& choices);
    bool held_end(const std::vector<double>& q0, const std::vector<double>& usual, const Pose& to,
                  const Kinematics::Solutions* at_end, std::vector<double>& q, Eigen::Vector3d& end_axis, bool start_exact,
                  PoleChoices& choices, bool& flipped) const;
    bool turn_between(const std::vector<double>& q0, const Pose& from, const Pose& to, const std::vector<double>& q,
                      double& worst);
    Eigen::Vector3d axis_at(const std::vector<double>& q) const;

    const Kinematics& kin_;
    const Machine& machine_;
    Eigen::Vector3d pole_ = Eigen::Vector3d::UnitZ();
    bool checks_ = false;
    bool polar_ = false;                   // Kinematics::is_polar
    std::size_t c_ = 0, b_ = 0;            // the rotaries' joints (rotary_joints() order)
    AngleLimit region_, short_turn_, wide_turn_;  // the tests of the angles passage compares
    double exact_start_;                   // a start within 1e-6 degrees of its axis: a dot at least this
    double chord_limit_;                   // hold's chord within its limit (a constant of the machine)
    std::vector<double> probe_;            // scratch
    PoleTurn turn_;
    struct KnownAxis {
        bool valid = false;
        std::uint64_t rotary[2] = {};  // the rotaries' bits (a signed zero counts: the sine keeps its sign)
        Eigen::Vector3d axis;
        bool holds(std::uint64_t c, std::uint64_t b) const { return valid & (rotary[0] == c) & (rotary[1] == b); }
    };
    KnownAxis known_[2];  // see axis_at
    int known_next_ = 0;
};

// Scratch space the motion stage's pole functions reuse move after move.
struct PoleScratch {
    std::vector<double> q, lerp, prev, cur;
};

// Across the pole (cross): the end on another branch of a vector move from q0 to `end_tip` whose
// programmed axis follows `arc`, reached with the rotaries turning linearly, when the tool axis
// stays within the angle tolerance of the arc and the rotaries turn clearly less than the
// continuous branch does (`measured`: its split's travel, when `split_ok`; else the estimate on a
// few points). `solutions`: of the end axis. True with the end in `end` and the axis's largest
// deviation in `angle`.
bool pole_crossing(const Kinematics& kin, const std::vector<double>& q0, const Eigen::Vector3d& end_tip, const GreatArc& arc,
                   const Kinematics::Solutions& solutions, bool split_ok, double measured, PoleScratch& scratch,
                   std::vector<double>& end, double& angle);

// Join (from a held start): the longest first part s1 of a vector move from q0 (tips p0_tip to
// p1_tip, axis along `arc`) over which the rotaries can turn linearly onto the exact solution at
// s1 with the tool axis within the angle tolerance of the arc; halved down to 2^-12 of the move.
// 0 when none does; else s1, with its joints in `q1` and the axis's largest deviation in `worst`.
double pole_join(const Kinematics& kin, const std::vector<double>& q0, const Eigen::Vector3d& p0_tip,
                 const Eigen::Vector3d& p1_tip, const GreatArc& arc, PoleScratch& scratch, std::vector<double>& q1,
                 double& worst);

// Re-index (leaving a pole): at the start the tool axis is on a rotary axis, so that joint was
// free and kept its old angle, but the path leaves in a direction that needs another. The move
// parameter just off the start (1e-4 rad of its turn) at which to solve, far enough that the joint
// is no longer free; 0 when the start is not on a pole (`at_start`: its orientation solutions) or
// the move does not turn.
double pole_leaving_probe(const Kinematics::Solutions& at_start, std::size_t rotaries, const Eigen::Vector3d& from,
                          const Eigen::Vector3d& to);
// From the joints solved there (`probe`): the start's joints with each rotary that jumps by more
// than a degree turned to its probe value, the tip held at `tip`, in `turned`; left empty when
// none jumps (the move needs no re-index). Not ok when the turned joints cannot hold the tip.
IkResult pole_reindex(const Kinematics& kin, const std::vector<double>& q0, const std::vector<double>& probe,
                      const Eigen::Vector3d& tip, std::vector<double>& turned);

}  // namespace xlate5
