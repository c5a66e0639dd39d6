// The joints' limits, in one place: what "inside" means, and which orientation solution and
// 360-degree turn a rotary takes under them. The policy of the planner stage (planner.cpp and the
// motion stage it drives call it; Kinematics::inverse uses it to keep its contract). May call:
// the machine data and Kinematics' plain queries (orientation_solutions, rotary_joints).
#pragma once
#include <Eigen/Core>
#include <vector>

#include "translators/kinematics.hpp"
#include "translators/machine.hpp"

namespace xlate5 {

// True when v lies inside the joint's limits (within kLimitSlack).
bool inside_limits(const Joint& joint, double v);

// Checks every joint of q against its limits.
IkResult check_limits(const Machine& machine, const std::vector<double>& q);

// Sets the rotary joints of q to reach tool axis `axis`: of the (up to two) orientation
// solutions and their 360-degree turns, the one inside the limits nearest `previous`. A joint on
// its pole (parallel to the tool axis) is free and takes free_value[j] (its previous value, or
// where the motion stage interpolates it across a move).
IkResult orient_within_limits(const Kinematics& kin, const Eigen::Vector3d& axis, const std::vector<double>& previous,
                              const std::vector<double>& free_value, std::vector<double>& q);

// The same, restricted to orientation solution `branch` (0 or 1): the motion stage tries the
// other branch where the continuous one would swing a joint round a pole.
IkResult orient_on_branch(const Kinematics& kin, const Eigen::Vector3d& axis, int branch, const std::vector<double>& previous,
                          const std::vector<double>& free_value, std::vector<double>& q);

// The nearest turn of the nearest solution whatever the limits: the continuous solution, to tell
// where a path leaves them. Free joints keep their previous value.
IkResult orient_continuous(const Kinematics& kin, const Eigen::Vector3d& axis, const std::vector<double>& previous,
                           std::vector<double>& q);

}  // namespace xlate5
