// SPDX-License-Identifier: GPL-3.0-or-later
// The kinematics' face, as LinuxCNC's trtfuncs.c: forward(q), inverse(pose, previous), the
// orientation solutions of a tool axis with the position solve (which the planner combines under
// its own policy), and the path bound (how far the firmware's joint-space path strays). Any
// machine with up to two rotary joints, no machine's own formula: the general chain solver
// (chain.cpp, Paden-Kahan subproblems 1 and 2) is the specification; the fast paths
// (table_table.hpp, orientation_shortcut.hpp) are chosen once at load where the machine's shape
// allows them, and the tests hold them equal to it. Used by the planner, the motion stage,
// calibration and --inverse. May call: the machine data, and joint_limits (the one definition of
// the limits) for the choice inverse() makes.
#pragma once
#include <Eigen/Core>
#include <limits>
#include <string>
#include <vector>

#include "translators/kinematics/chain.hpp"
#include "translators/kinematics/kinematics_types.hpp"
#include "translators/kinematics/orientation_shortcut.hpp"
#include "translators/kinematics/path_bound.hpp"
#include "translators/kinematics/polar.hpp"
#include "translators/kinematics/table_table.hpp"
#include "translators/machine/machine.hpp"

namespace xlate5 {

// The angle (degrees) between two unit vectors, from their dot product.
double angle_of_dot(double dot);

// For bounds, which only have to be safe, without an acos or asin:
// the square of the angle (radians) between two unit vectors with dot product d, at most:
// 4 tan^2(phi / 2) = 4 (1 - d) / (1 + d) >= phi^2 (tan x >= x), within a few parts in phi^2 of it
// for small turns; infinite past a right angle;
double turn_squared_at_most(double d);
// and the chord between two unit vectors below which their angle is within `degrees`: 2 sin of
// half of it, made shorter by 1e-12 of itself than rounding could move it (0 outside (0, 180)).
double chord_within(double degrees);

// The least dot with angle_of_dot(dot) < degrees, for a limit so small that only dots a few
// ulps below 1 pass (1e-6 degrees: 1 and the double below it; at most 64 of them, else NaN).
// Every dot below it fails: acos only grows as dot falls (test_kinematics checks each double
// within 1e-12 of 1, where AngleLimit would take the acos; past that AngleLimit's own reason
// holds), so `dot >= least` is the acos's verdict without the acos.
double least_dot_below(double degrees);

// angle_of_dot(dot) compared with a fixed limit: the same verdict, with the acos only when dot is
// within 1e-12 of the limit's cosine. Outside that window the angle is more than 1e-12 radians
// from the limit (|d acos / d dot| >= 1), far more than the few ulps by which acos, the product
// with kDegPerRad and the limit's cosine can be off. A limit outside (0, 180) degrees always
// takes the acos.
class AngleLimit {
public:
    explicit AngleLimit(double degrees);
    double degrees() const { return degrees_; }
    // angle_of_dot(dot) < degrees()
    bool below(double dot) const {
        if (dot > high_) return true;
        if (dot < low_) return false;
        return angle_of_dot(dot) < degrees_;
    }
    // angle_of_dot(dot) > degrees()
    bool above(double dot) const {
        if (dot > high_) return false;
        if (dot < low_) return true;
        return angle_of_dot(dot) > degrees_;
    }

private:
    double degrees_;
    double low_ = -std::numeric_limits<double>::infinity(), high_ = std::numeric_limits<double>::infinity();
};

class Kinematics {
public:
    // Precomputes the orientation structure; throws MachineError for a layout outside the family.
    explicit Kinematics(const Machine& machine);

    const Machine& machine() const { return machine_; }

    // Joint values (mm, degrees) -> tip and tool axis in the part frame.
    Pose forward(const std::vector<double>& q) const;
    // forward(q).axis to the last bit, without the tip's translations (the pole checks ask only that).
    Eigen::Vector3d tool_axis(const std::vector<double>& q) const;

    // The firmware's path from joints qa to qb (every joint at a constant rate): its end poses
    // (path_end, or path_bound().near_end without an FK), and upper bounds on how far, anywhere
    // along it, the tip (mm) and the tool axis (a unit vector) leave the chords between those
    // ends (path_bound(), path_bound.hpp). Cheaper than sampling the path.
    using PathEnd = xlate5::PathEnd;
    using SolvedEnd = xlate5::SolvedEnd;
    using PathBound = xlate5::PathBound;
    PathEnd path_end(const double* q) const;
    const JointPathBound& path_bound() const { return bound_; }

    // Joints reaching `pose`: of its solutions (both orientation branches, their 360-degree
    // turns), the one inside the joint limits nearest `previous`. A joint whose axis is parallel to
    // the tool axis keeps its previous value.
    IkResult inverse(const Pose& pose, const std::vector<double>& previous, std::vector<double>& q) const;

    // Sets the linear joints of q so the tip reaches `tip`, rotary joints as they are in q;
    // `axis`, when given, receives the tool axis of that configuration.
    // `end`, when given, receives the solution's SolvedEnd where the solve can give it cheaply.
    // `chosen`, when it names a solution, says that q's rotaries are that orientation solution's
    // angles (orient_within_limits's report): the solve may take their cosines and sines from it.
    IkResult solve_position(const Eigen::Vector3d& tip, std::vector<double>& q, Eigen::Vector3d* axis = nullptr,
                            SolvedEnd* end = nullptr, ChosenSolution chosen = {}) const;
    // solve_position's general path in Eigen's own products, which the scalar solve equals bit
    // for bit (the closed form of has_two_turns() to rounding). Apart for the tests that hold the
    // two against each other.
    IkResult solve_position_general(const Eigen::Vector3d& tip, std::vector<double>& q, Eigen::Vector3d* axis = nullptr,
                                    SolvedEnd* end = nullptr) const;

    // The raw orientation solutions of a tool axis (see OrientationSolutions).
    using Solutions = OrientationSolutions;
    Solutions orientation_solutions(const Eigen::Vector3d& axis) const;
    // orientation_solutions is the shortcut where the machine's rotary axes allow it (on()) and
    // it answers (solve() false: it leaves the axis to the general path), else the general path:
    // the same bits. Apart for the tests that hold the two against each other.
    const OrientationShortcut& orientation_shortcut() const { return orient_; }
    Solutions orientation_solutions_general(const Eigen::Vector3d& axis) const;
    const std::vector<int>& rotary_joints() const { return frame_.rotary; }

    // True when (theta1 + 180, -theta2) gives the same tool axis as (theta1, theta2) for every
    // angle: the second rotary is normal to the first and the tool axis (at zero) lies along the
    // first (rw2's A/B head, A/C and B/C tables). Then the other orientation branch is an affine
    // image of the first, so angle-form moves can be carried over to it exactly.
    bool has_flip() const { return frame_.flip; }

    // The machine has the TwoTurns shape (pentarod's A/C table): forward(), tool_axis() and the
    // position solve are in closed form there, equal to the chain walk's products to rounding
    // rather than to the bit (the tests hold them to it).
    bool has_two_turns() const { return turns_.on(); }

    // A polar machine (core-rtheta): the part turns about one rotary (C) so that the tip lies in
    // the plane an absent linear joint (Y, held at its home) leaves; the other rotary (B) tilts in
    // that plane, and the tool axis at B = 0 is C's pole. There C comes from the tip, not from the
    // tool axis, whose azimuth rounding makes arbitrary near the pole (docs/machines.md, polar.hpp).
    bool is_polar() const { return polar_.on(); }

private:
    // The polar policy sits on top of the solve without it (solve_varying).
    friend class PolarTurn;

    Pose forward(const double* q, double* lever_arm, double* arms = nullptr) const;
    // solve_position's path for a Jacobian that varies, in the walk's scalars (chain.cpp).
    IkResult solve_scalar(const Eigen::Vector3d& tip, std::vector<double>& q, Eigen::Vector3d* axis, SolvedEnd* end) const;
    // solve_two_turns where the machine has that shape, else solve_scalar.
    IkResult solve_varying(const Eigen::Vector3d& tip, std::vector<double>& q, Eigen::Vector3d* axis, SolvedEnd* end,
                           ChosenSolution chosen) const;

    // What the loading takes once (kinematics.cpp), each step's result a value of chain.hpp or
    // the fast paths' own, in this order.
    Machine machine_;
    std::vector<ChainLink> part_links_, tool_links_;  // machine_'s chains, compiled for the walk
    OrientationFrame frame_;      // the orientation product's rotaries, axes and flip
    OrientationShortcut orient_;  // orientation_solutions' fast path (orientation_shortcut.hpp)
    JointPathBound bound_;        // see path_bound()
    PositionSolve position_;      // the position solve's unknowns and constants
    SolvedEndPlan ends_;          // how the solve gives its SolvedEnd
    TwoTurns turns_;  // forward, tool_axis and the position solve's closed form (table_table.hpp)
    PolarTurn polar_;             // see is_polar()
};

}  // namespace xlate5
