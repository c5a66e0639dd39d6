// SPDX-License-Identifier: GPL-3.0-or-later
// A polar machine (core-rtheta, Kinematics::is_polar): C from the tip where the tool axis cannot
// say. A policy on top of the position solve, found once at load. May call: the kinematics' solve
// and tool axis, and joint_limits.
#pragma once
#include <Eigen/Core>
#include <vector>

#include "translators/kinematics/kinematics_types.hpp"

namespace xlate5 {

class Kinematics;

class PolarTurn {
public:
    // Finds the shape in kin, whose tool axis and position solve are loaded; on() false otherwise.
    // `constant_jacobian`: kin's position solve has a fixed Jacobian (then it is no polar machine).
    void load(const Kinematics& kin, bool constant_jacobian);
    bool on() const { return on_; }
    // Kinematics::solve_position on a polar machine: as before while the absent joint stays
    // within its slack, else with turn()'s rotaries.
    IkResult solve(const Kinematics& kin, const Eigen::Vector3d& tip, std::vector<double>& q, Eigen::Vector3d* axis,
                   SolvedEnd* end, ChosenSolution chosen) const;

private:
    // C turned to the nearest angle that puts the tip in the absent joint's plane (and B's sign
    // flipped when that keeps the axis nearer), when the tool axis moves by at most
    // kPolarSnapDegrees doing so. False: q left as it was.
    bool turn(const Kinematics& kin, const Eigen::Vector3d& tip, std::vector<double>& q) const;

    bool on_ = false;
    int c_ = -1, b_ = -1, absent_ = -1;
};

}  // namespace xlate5
