// SPDX-License-Identifier: GPL-3.0-or-later
// The split's points: the programmed pose at a move parameter s (the tip on its line, the tool
// axis on its great circle) and the joints solved there, continuous from the point before or on
// a branch asked for, inside the limits. For the split to tolerance (split.hpp) and for the
// motion stage's pole handling. May call: kinematics, joint_limits.
#pragma once
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

class SplitPoints {
public:
    explicit SplitPoints(const Kinematics& kinematics);

    // The orientation solutions of an axis (remembered: one move's end is the next one's start),
    // and of an axis the caller has already solved, remembered for it.
    const Kinematics::Solutions& solutions_of(const Eigen::Vector3d& axis) const { return solutions_.of(axis); }
    void remember_solutions(const Kinematics::Solutions& solutions) const { solutions_.remember(solutions); }
    // The programmed axis's great circle, and the programmed pose at move parameter s.
    const GreatArc& arc_of(const PlannedMove& mv) const;
    Pose pose_at(const PlannedMove& move, double s) const;
    IkResult solve_at(const PlannedMove& move, double s, const std::vector<double>& previous, std::vector<double>& q,
                      int branch = -1) const;

    // solve_at's steps under the vector form: the programmed pose at s and its orientation
    // solutions (the split's try at s and its tries of the other branch share them); the rotaries
    // from `previous` (the continuous solution, or `branch`'s); the linear joints and the limits.
    struct Target {
        Pose pose;
        Kinematics::Solutions solutions;
    };
    void target_at(const PlannedMove& move, double s, Target& target) const;
    // `chosen` receives which of target.solutions q's rotaries took, for place.
    IkResult orient_at(const PlannedMove& move, double s, const Target& target, const std::vector<double>& previous,
                       std::vector<double>& q, int branch, ChosenSolution& chosen) const;
    IkResult place(const Target& target, std::vector<double>& q, ChosenSolution chosen) const;
    // The rotary joints of a and b are the same to the bit.
    bool same_rotaries(const std::vector<double>& a, const std::vector<double>& b) const;
    // An OutOfLimits result when the continuous solution at s (from `previous`) is outside a
    // rotary joint's limits.
    IkResult leaves_limits(const PlannedMove& move, double s, const std::vector<double>& previous) const;

private:
    const Kinematics& kin_;
    const Machine& machine_;
    LimitBox limits_;  // check_limits' verdict for the split's points (nearly all inside: no result built)
    SolutionCache solutions_;
    // The programmed axis's great circle of the move being split: its angle (an acos and a sine)
    // once per move, not once per try and sample point. Keyed by the two axes.
    mutable GreatArc arc_{Eigen::Vector3d::UnitZ(), Eigen::Vector3d::UnitZ()};
    mutable std::vector<double> lerp_, cont_;  // scratch (no allocation per point)
};

}  // namespace xlate5
