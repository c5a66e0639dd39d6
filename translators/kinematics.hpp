// The math, used by the planner, the motion stage, calibration and --inverse: forward kinematics
// and the closed-form inverse of any machine with up to two rotary joints (Paden-Kahan
// subproblems 1 and 2). No machine has its own formula here. May call: the machine data, and
// joint_limits for the choice inverse() makes.
//
// The contract is forward(q) and inverse(pose, previous). Below them, plain queries that the
// planner combines under its own policy: the orientation solutions per branch and the position
// solve for given rotaries.
#pragma once
#include <Eigen/Core>
#include <string>
#include <vector>

#include "translators/machine.hpp"

namespace xlate5 {

// Tip position and tool axis (unit, tip -> holder), both in the part frame.
struct Pose {
    Eigen::Vector3d tip = Eigen::Vector3d::Zero();
    Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();
};

enum class IkStatus { Ok, Unreachable, OutOfLimits, Singular };

struct IkResult {
    IkStatus status = IkStatus::Ok;
    std::string message;  // what went wrong, for the error that names the input line
    bool ok() const { return status == IkStatus::Ok; }
};

class Kinematics {
public:
    // Precomputes the orientation structure; throws MachineError for a layout outside the family.
    explicit Kinematics(const Machine& machine);

    const Machine& machine() const { return machine_; }

    // Joint values (mm, degrees) -> tip and tool axis in the part frame.
    Pose forward(const std::vector<double>& q) const;

    // Joints reaching `pose`: of its solutions (both orientation branches, every 360-degree
    // turn), the one inside the joint limits nearest `previous`. A joint whose axis is parallel to
    // the tool axis keeps its previous value.
    IkResult inverse(const Pose& pose, const std::vector<double>& previous, std::vector<double>& q) const;

    // Sets the linear joints of q so the tip reaches `tip`, rotary joints as they are in q;
    // `axis`, when given, receives the tool axis of that configuration.
    IkResult solve_position(const Eigen::Vector3d& tip, std::vector<double>& q, Eigen::Vector3d* axis = nullptr) const;

    // The raw orientation solutions, in degrees: each has one value per rotary joint in
    // `rotary_joints()` order (NaN where that joint is free). Fixed size: no allocation per move.
    struct Solutions {
        int count = 0;
        double angle[2][2] = {};
        std::size_t size() const { return std::size_t(count); }
        bool empty() const { return count == 0; }
    };
    Solutions orientation_solutions(const Eigen::Vector3d& axis) const;
    const std::vector<int>& rotary_joints() const { return rotary_; }

    // True when (theta1 + 180, -theta2) gives the same tool axis as (theta1, theta2) for every
    // angle: the second rotary is normal to the first and the tool axis (at zero) lies along the
    // first (rw2's A/B head, A/C and B/C tables). Then the other orientation branch is an affine
    // image of the first, so angle-form moves can be carried over to it exactly.
    bool has_flip() const { return flip_; }

private:
    struct Factor;
    void eval(const std::vector<ChainElement>& chain, const std::vector<double>& q, Eigen::Matrix3d& R,
              Eigen::Vector3d& t, Eigen::Vector3d* linear_dirs) const;

    Machine machine_;
    std::vector<int> rotary_;          // rotary joint indices in the order of the orientation product
    std::vector<double> sign_;         // +1 tool chain, -1 part chain (the part rotation enters inverted)
    std::vector<Eigen::Vector3d> w_;   // rotation axes in the frame of u' = G0^T u
    Eigen::Matrix3d g0_ = Eigen::Matrix3d::Identity();
    Eigen::Vector3d p_ = Eigen::Vector3d::UnitZ();
    bool flip_ = false;
};

// Wraps an angle in degrees to (-180, 180].
double wrap180(double degrees);

}  // namespace xlate5
