// The math: forward kinematics and the closed-form inverse of any machine with up to two
// rotary joints (Paden-Kahan subproblems 1 and 2). No machine has its own formula here.
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

    // Sets the linear joints of q so the tip reaches `tip`, rotary joints as they are in q;
    // `axis`, when given, receives the tool axis of that configuration.
    IkResult solve_position(const Eigen::Vector3d& tip, std::vector<double>& q, Eigen::Vector3d* axis = nullptr) const;

    // Sets the rotary joints of q to reach tool axis `axis`: of the (up to two) solutions and
    // their 360-degree turns, the one inside the limits nearest `previous`. A joint whose axis is
    // parallel to the tool axis keeps its previous value.
    // `free_hint`, when given, is the value a free joint takes instead of its previous one (the
    // motion stage interpolates a free joint across a move).
    // `branch` 0 or 1 restricts the choice to that orientation solution (the motion stage tries
    // the other branch where the continuous one would swing a joint round a pole).
    // `limited` false: the nearest turn of the nearest branch whatever the limits (the continuous
    // solution, to tell where a path leaves them).
    IkResult solve_orientation(const Eigen::Vector3d& axis, const std::vector<double>& previous,
                               std::vector<double>& q, const std::vector<double>* free_hint = nullptr, int branch = -1,
                               bool limited = true) const;

    // Both: orientation from `pose.axis`, then position.
    IkResult inverse(const Pose& pose, const std::vector<double>& previous, std::vector<double>& q) const;

    // Checks every joint of q against its limits.
    IkResult check_limits(const std::vector<double>& q) const;

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
