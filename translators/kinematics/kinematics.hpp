// SPDX-License-Identifier: GPL-3.0-or-later
// The kinematics' face, as LinuxCNC's trtfuncs.c: forward(q), inverse(pose, previous), the
// orientation solutions of a tool axis with the position solve (which the planner combines under
// its own policy), and the path bound (how far the firmware's joint-space path strays). Any
// machine with up to two rotary joints, no machine's own formula: the general chain solver
// (chain.cpp, Paden-Kahan subproblems 1 and 2) is the specification; the fast paths
// (two_turns.hpp, orientation_shortcut.hpp) are chosen once at load where the machine's shape
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
#include "translators/kinematics/two_turns.hpp"
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

    // The firmware's path from joints qa to qb (every joint at a constant rate): its end poses,
    // and upper bounds on how far, anywhere along it, the tip (mm) and the tool axis (a unit
    // vector) leave the chords between those ends. Cheaper than sampling the path; see
    // path_bound.cpp for the derivation.
    using PathEnd = xlate5::PathEnd;
    using SolvedEnd = xlate5::SolvedEnd;
    PathEnd path_end(const double* q) const;
    // The PathEnd at joints q near a solved end (the end rounded to the printed decimals), with
    // no FK: the solved pose with the slack that moving its joints to q can add (each rotary
    // turns the tip by at most its angle times the tip's distance from its axis, a linear joint
    // moves it by its own travel) and the arms grown by how far the tip can move at all. False
    // when that cannot be bounded (a linear joint without limits: no reach).
    bool near_end(const SolvedEnd& solved, const double* q, PathEnd& out) const;
    struct PathBound {
        double tip = 0, axis = 0;
    };
    PathBound joint_path_bound(const PathEnd& a, const double* qa, const double* qb) const;
    // joint_path_bound for any order of the terms (it takes a shorter path for some orders; the
    // tests hold it against this one).
    PathBound joint_path_bound_general(const PathEnd& a, const double* qa, const double* qb) const;
    // joint_path_bound's bound for the tool axis alone, for a turn of any size.
    double axis_path_bound(const double* qa, const double* qb) const;
    // The machine's reach as a path end (lever arms only, no pose): the tip's largest distance
    // from each rotary axis anywhere inside the joint limits. joint_path_bound(reach(), qa, qb)
    // bounds a path between joints inside the limits without an FK; has_reach() is false when a
    // linear joint has no limits.
    bool has_reach() const { return has_reach_; }
    const PathEnd& reach() const { return reach_; }
    // How far the tip can move between joints qa and qb (each joint on its own, added): an upper
    // bound by the reach, for joints inside the limits.
    double reach_shift(const double* qa, const double* qb) const;

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
    // orientation_solutions is the shortcut where the machine's rotary axes allow it and it
    // answers (false: it leaves the axis to the general path), else the general path: the same
    // bits. Apart for the tests that hold the two against each other.
    bool has_orientation_shortcut() const { return orient_.on(); }
    bool orientation_shortcut(const Eigen::Vector3d& axis, Solutions& out) const;
    Solutions orientation_solutions_general(const Eigen::Vector3d& axis) const;
    const std::vector<int>& rotary_joints() const { return rotary_; }

    // True when (theta1 + 180, -theta2) gives the same tool axis as (theta1, theta2) for every
    // angle: the second rotary is normal to the first and the tool axis (at zero) lies along the
    // first (rw2's A/B head, A/C and B/C tables). Then the other orientation branch is an affine
    // image of the first, so angle-form moves can be carried over to it exactly.
    bool has_flip() const { return flip_; }

    // The machine has the TwoTurns shape (pentarod's A/C table): forward(), tool_axis() and the
    // position solve are in closed form there, equal to the chain walk's products to rounding
    // rather than to the bit (the tests hold them to it).
    bool has_two_turns() const { return turns_.on(); }

    // A polar machine (core-rtheta): the part turns about one rotary (C) so that the tip lies in
    // the plane an absent linear joint (Y, held at its home) leaves; the other rotary (B) tilts in
    // that plane, and the tool axis at B = 0 is C's pole. There C comes from the tip, not from the
    // tool axis, whose azimuth rounding makes arbitrary near the pole (docs/machines.md).
    bool is_polar() const { return polar_.on; }

private:
    // The constructor's steps, in this order (kinematics.cpp).
    void load_orientation(const Machine& machine);
    void load_bound_terms(const Machine& machine);
    void load_reach(const Machine& machine);
    void load_position_solve(const Machine& machine);
    void load_solved_ends(const Machine& machine);
    // solve_position on a polar machine: as before while the absent joint stays within its slack,
    // else with polar_turn's rotaries.
    IkResult solve_polar(const Eigen::Vector3d& tip, std::vector<double>& q, Eigen::Vector3d* axis, SolvedEnd* end,
                         ChosenSolution chosen) const;
    // C turned to the nearest angle that puts the
    // tip in the absent joint's plane (and B's sign flipped when that keeps the axis nearer), when
    // the tool axis moves by at most kPolarSnapDegrees doing so. False: q left as it was.
    bool polar_turn(const Eigen::Vector3d& tip, std::vector<double>& q) const;
    void find_polar();
    struct Polar {
        bool on = false;
        int c = -1, b = -1, absent = -1;
    } polar_;

    // Base -> a chain's end (rotation, translation); `linear_dirs`, when given, receives each linear
    // joint's direction.
    void eval(const std::vector<ChainLink>& chain, const double* q, Eigen::Matrix3d& R, Eigen::Vector3d& t,
              Eigen::Vector3d* linear_dirs) const;
    Pose forward(const double* q, double* lever_arm, double* arms = nullptr) const;
    // solve_position's path for a Jacobian that varies, in the walk's scalars (chain.cpp).
    IkResult solve_scalar(const Eigen::Vector3d& tip, std::vector<double>& q, Eigen::Vector3d* axis, SolvedEnd* end) const;
    // solve_two_turns where the machine has that shape, else solve_scalar.
    IkResult solve_varying(const Eigen::Vector3d& tip, std::vector<double>& q, Eigen::Vector3d* axis, SolvedEnd* end,
                           ChosenSolution chosen) const;
    // The position solve's 3x3 Jacobian from the chains' linear directions; false when singular.
    bool linear_jacobian(const Eigen::Matrix3d& Rp, const Eigen::Vector3d* part_dirs, const Eigen::Vector3d* tool_dirs,
                         Eigen::Matrix3d& J) const;

    // The moving elements of the chain seen from the part (the part chain inverted, then the tool
    // chain), in that order, for the bound; linear joints ahead of every rotary are left out.
    struct BoundTerm {
        int joint = 0;
        bool rotary = false;
        double scale = 1;  // the axis's length as written
        int arm = 0;       // rotary: its index in PathEnd::arm
    };
    std::vector<BoundTerm> terms_;
    // terms_ when it is its rotaries and then its linear joints alone (joint_path_bound_split).
    bool bound_split_ = false;
    int bound_rotary_ = 0, bound_count_ = 0;
    BoundTerm bound_[kMaxJoints];
    PathBound joint_path_bound_split(const PathEnd& a, const double* qa, const double* qb) const;

    Machine machine_;
    std::vector<ChainLink> part_links_, tool_links_;  // machine_'s chains, compiled for the walk
    std::vector<int> rotary_;          // rotary joint indices in the order of the orientation product
    std::vector<double> sign_;         // +1 tool chain, -1 part chain (the part rotation enters inverted)
    std::vector<Eigen::Vector3d> w_;   // rotation axes in the frame of u' = G0^T u
    Eigen::Matrix3d g0_ = Eigen::Matrix3d::Identity();
    Eigen::Vector3d p_ = Eigen::Vector3d::UnitZ();
    bool flip_ = false;
    OrientationShortcut orient_;  // orientation_solutions' fast path (orientation_shortcut.hpp)
    std::vector<int> linear_;               // the first three linear joints: the position solve's unknowns
    bool constant_jacobian_ = false;        // no rotation ahead of a linear joint: its inverse is fixed
    PathEnd reach_;                         // see reach()
    bool has_reach_ = false;
    std::vector<double> shift_per_unit_;    // per joint: mm of tip per unit of the joint, at most
    double jacobian_inverse_[9] = {};       // that inverse, row by row (constant_jacobian_)
    // For the solve's SolvedEnd: each rotary element's axis line, in forward()'s walk order, is
    // moved by the linear joints ahead of it in its own chain (a mask of joints); the tip by those
    // of the tool chain. False when a linear joint appears twice (a machine built by hand).
    struct LineShift {
        bool tool = false;      // in the tool chain (else the part chain)
        unsigned linear = 0;    // bit j: linear joint j is ahead of it in that chain
    };
    std::vector<LineShift> line_shifts_;
    // The scalar solve (solve_scalar): whether each unknown's linear joint is in the tool chain
    // and in the part chain; a tool chain of fresh linear links alone, and the identity times the
    // tool axis.
    struct SolveColumn {
        bool tool = false, part = false;
    };
    SolveColumn solve_cols_[3];
    bool tool_plain_ = false;
    double tool_up_[3] = {};
    std::vector<int> tool_linear_;      // the tool chain's linear joints (they carry the tip)
    TwoTurns turns_;  // forward, tool_axis and the position solve's closed form (two_turns.hpp)
    bool solved_ends_ = false;
    // near_end's terms, looked up once: each linear joint with its mm per unit, each rotary
    // element with its radians per unit and its arm.
    struct NearTerm {
        int joint = 0;
        double per_unit = 0;
        int arm = -1;          // rotary: its index in PathEnd::arm; -1 for a linear joint
        double reach_per_unit = 0;  // the joint's shift_per_unit_ (reach_shift's term), on its first term only
    };
    std::vector<NearTerm> near_terms_;
    std::size_t near_linear_ = 0;  // near_terms_' linear joints, all ahead of its rotary elements
    int arm_count_ = 0;  // rotary elements, the entries of PathEnd::arm in use
};

}  // namespace xlate5
