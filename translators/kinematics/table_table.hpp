// SPDX-License-Identifier: GPL-3.0-or-later
// The two-turn table's closed form (table-table inverse kinematics, pentarod's A/C table): a part
// chain of two turns about +-1 times coordinate axes k1 != k2, both through the origin, and a
// tool chain of three fresh linear links giving the three unknowns. forward(), the tool axis and
// the position solve in closed form, their constants taken once at load; equal to the chain
// walk's products to rounding rather than to the bit (test_kinematics holds them to it).
// May call: nothing but the math library.
#pragma once
#include <Eigen/Core>
#include <vector>

#include "translators/kinematics/chain.hpp"
#include "translators/kinematics/kinematics_types.hpp"

namespace xlate5 {

class TwoTurns {
public:
    // The machine's compiled chains and the position solve's three unknowns (linear joints);
    // rotary: the orientation product's joints, `orient_terms` whether its solutions carry
    // their atan2 terms; `tool_up`: the identity times the tool axis; `ends`: the solve may give
    // SolvedEnds. on() is false when the machine has another shape.
    void load(const std::vector<ChainLink>& part, const std::vector<ChainLink>& tool, const std::vector<int>& linear,
              const std::vector<int>& rotary, bool orient_terms, const double* tool_up, bool ends);
    bool on() const { return pattern >= 0; }

    // Kinematics::forward at q; with `lever_arm`, the tip's largest distance from a turn's axis
    // (and each in `arms`).
    Pose forward(const double* q, double* lever_arm, double* arms) const;
    Eigen::Vector3d tool_axis(const double* q) const;
    // Kinematics::solve_position: sets the three unknowns of q so the tip reaches `tip`.
    IkResult solve(const Eigen::Vector3d& tip, std::vector<double>& q, Eigen::Vector3d* axis, SolvedEnd* end,
                   ChosenSolution chosen) const;

    int pattern = -1;  // k1 * 3 + k2; -1: the machine has another shape
    int j1 = 0, j2 = 0;
    double sign1 = 1, sign2 = 1;
    double point2[3] = {}, axis2[3] = {};           // the second turn's link, as the walk reads it
    double line0_point[3] = {}, line0_dir[3] = {};  // the first turn's axis line (R, t still the identity and zero)
    int tool_joint[3] = {};
    double tool_dir[3][3] = {};  // the tool links' axes, in chain order
    double col_inv[9] = {};      // the inverse of the matrix of the unknowns' directions (columns), row by row
    bool singular = false;       // the directions do not span space: no position solve
    int r1 = -1, r2 = -1;        // the turns' columns of OrientationSolutions::angle (-1: no shortcut gives them)
    int linear[3] = {};          // the unknowns' joints
    double tool_up[3] = {};
    bool ends = false;

private:
    template <int k1, int k2>
    Pose forward_at(const double* q, double* lever_arm, double* arms) const;
    template <int k1, int k2>
    IkResult solve_at(const Eigen::Vector3d& tip, std::vector<double>& q, Eigen::Vector3d* axis, SolvedEnd* end,
                      ChosenSolution chosen) const;
};

}  // namespace xlate5
