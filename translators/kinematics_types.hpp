// The values kinematics and the joint-limit policy exchange: a pose, the raw orientation
// solutions of a tool axis, the result of a solve, and angle wrapping. Calls nothing.
#pragma once
#include <Eigen/Core>
#include <cmath>
#include <cstddef>
#include <string>

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

// The raw orientation solutions of tool axis `axis`, in degrees: each has one value per rotary
// joint in Kinematics::rotary_joints() order (NaN where that joint is free). Fixed size: no
// allocation per move.
struct OrientationSolutions {
    Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();  // the axis they reach, as asked
    int count = 0;
    double angle[2][2] = {};
    std::size_t size() const { return std::size_t(count); }
    bool empty() const { return count == 0; }
};

// Wraps an angle in degrees to (-180, 180].
inline double wrap180(double degrees) {
    // fmod returns an |x| < 360 as it is (exactly): the call only where it can change something.
    double r = std::abs(degrees) < 360.0 ? degrees : std::fmod(degrees, 360.0);
    if (r <= -180.0) r += 360.0;
    if (r > 180.0) r -= 360.0;
    return r;
}

}  // namespace xlate5
