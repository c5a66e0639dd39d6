// SPDX-License-Identifier: GPL-3.0-or-later
// The joints' limits, in one place: what "inside" means, and which orientation solution and
// 360-degree turn a rotary takes under them. The planner's policy (planner.cpp and the motion
// stage it drives call it); Kinematics::inverse uses it to keep its contract. Below kinematics:
// it is handed the solutions and may call nothing but the machine data.
#pragma once
#include <Eigen/Core>
#include <string>
#include <vector>

#include "translators/kinematics/kinematics_types.hpp"
#include "translators/machine/machine.hpp"

namespace xlate5 {

// True when v lies inside the joint's limits (within kLimitSlack).
bool inside_limits(const Joint& joint, double v);

// True when every joint of q is inside its limits (a NaN is not): check_limits's verdict, with
// no result to build (nearly every move is inside).
bool within_limits(const Machine& machine, const std::vector<double>& q);

// within_limits's verdict from the limits with their slack worked out once (the same values,
// the same comparisons), for the planner's check of every move's end: no joint record read and
// no slack added a joint.
class LimitBox {
public:
    explicit LimitBox(const Machine& machine);
    bool contains(const std::vector<double>& q) const {
        // A joint outside (or NaN: both comparisons false) ends the test: two compares and
        // branches a joint, none taken on the usual move, instead of the flags combined.
        const double* v = q.data();
        const double* lo = lo_.data();
        const double* hi = hi_.data();
        const std::size_t n = lo_.size();
        for (std::size_t j = 0; j < n; ++j)
            if (!(v[j] >= lo[j]) || !(v[j] <= hi[j])) return false;
        return true;
    }

private:
    std::vector<double> lo_, hi_;
};

// Checks every joint of q against its limits.
IkResult check_limits(const Machine& machine, const std::vector<double>& q);
// A joint value as the limit messages write it (mm or degrees, 3 decimals).
std::string joint_value_text(double v);

// The rotaries of q for one of `solutions` (Kinematics::orientation_solutions; `rotary` is
// Kinematics::rotary_joints()): of the solutions and their 360-degree turns, the one inside the
// limits nearest `previous`. A joint on its pole (parallel to the tool axis) is free and takes
// free_value[j] (its previous value, or where the motion stage interpolates it across a move).
// `chosen`, when given, is told which solution q now holds (ChosenSolution).
IkResult orient_within_limits(const Machine& machine, const std::vector<int>& rotary, const OrientationSolutions& solutions,
                              const std::vector<double>& previous, const std::vector<double>& free_value, std::vector<double>& q,
                              ChosenSolution* chosen = nullptr);

// The same without its shortcut for two rotaries and two solutions: for the tests that hold the
// shortcut against it.
IkResult orient_within_limits_general(const Machine& machine, const std::vector<int>& rotary, const OrientationSolutions& solutions,
                                      const std::vector<double>& previous, const std::vector<double>& free_value, std::vector<double>& q);

// The same, restricted to solution `branch` (0 or 1): the motion stage tries the other branch
// where the continuous one would swing a joint round a pole.
IkResult orient_on_branch(const Machine& machine, const std::vector<int>& rotary, const OrientationSolutions& solutions, int branch,
                          const std::vector<double>& previous, const std::vector<double>& free_value, std::vector<double>& q,
                          ChosenSolution* chosen = nullptr);

// The nearest turn of the nearest solution whatever the limits: the continuous solution, to tell
// where a path leaves them. Free joints keep their previous value.
IkResult orient_continuous(const Machine& machine, const std::vector<int>& rotary, const OrientationSolutions& solutions,
                           const std::vector<double>& previous, std::vector<double>& q);

}  // namespace xlate5
