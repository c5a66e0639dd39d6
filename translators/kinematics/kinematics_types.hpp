// SPDX-License-Identifier: GPL-3.0-or-later
// The values kinematics and the joint-limit policy exchange: the joint bound, a pose, the raw orientation
// solutions of a tool axis, the result of a solve, and angle wrapping. Calls nothing.
#pragma once
#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace xlate5 {

// The most joints a machine may have: the length of every fixed per-joint array (the emitter's,
// the split's, the path bound's), so none allocates per move. The emitter refuses a machine with
// more.
inline constexpr std::size_t kMaxJoints = 8;

// A value per joint, by joint number, owned by whatever carries it (a command, a planned move):
// the first machine.joints.size() are read, the rest are left as they are.
using Joints = std::array<double, kMaxJoints>;
// One bit a joint (bit j: joint j).
using JointBits = std::uint32_t;
static_assert(kMaxJoints <= 32, "JointBits holds one bit a joint");
// The joints of a joint vector (one value a machine joint) into an array's first entries.
inline void set_joints(Joints& to, const std::vector<double>& from) { std::copy(from.begin(), from.end(), to.begin()); }

// Tip position and tool axis (unit, tip -> holder), both in the part frame.
struct Pose {
    Eigen::Vector3d tip = Eigen::Vector3d::Zero();
    Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();
};

// An end of the firmware's path between two joint vectors (Kinematics::path_end): its pose, and
// the tip's largest distance from a rotary joint's axis.
struct PathEnd {
    Pose pose;
    double lever_arm = 0;          // the largest of `arm`
    double arm[kMaxJoints] = {};   // the distance from each rotary element's axis, in chain order (part chain, then tool chain)
    // An end bounded rather than measured (near_end): the true tip and tool axis are within
    // these of `pose` (mm, and a unit vector's length), and `arm` holds upper bounds.
    double tip_slack = 0, axis_slack = 0;
};

// An end the position solve found: its joints as solved and its PathEnd, which the solve gives
// for a few operations more than its own walk. `valid` is false when it did not (the machine's
// Jacobian is fixed, or no solve was made).
struct SolvedEnd {
    std::vector<double> q;
    PathEnd end;
    bool valid = false;
};

enum class IkStatus { Ok, Unreachable, OutOfLimits, Singular };

struct IkResult {
    IkStatus status = IkStatus::Ok;
    std::string message;  // what went wrong, for the error that names the input line
    bool linear = false;  // OutOfLimits: the joint past its limit is a linear one
    bool absent = false;  // OutOfLimits: ... one the machine does not have (held at its home)
    bool ok() const { return status == IkStatus::Ok; }
};

// The raw orientation solutions of tool axis `axis`, in degrees: each has one value per rotary
// joint in Kinematics::rotary_joints() order (NaN where that joint is free). Fixed size: no
// allocation per move.
struct OrientationSolutions {
    Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();  // the axis they reach, as asked
    int count = 0;
    double angle[2][2] = {};
    // From the orientation shortcut (has_terms): for each angle, (y, x) with atan2(y, x) its
    // radians (y carries the joint's sign), so that a position solve at these angles takes their
    // cosines and sines from them instead of calling sincos.
    bool has_terms = false;
    double terms[2][2][2] = {};
    std::size_t size() const { return std::size_t(count); }
    bool empty() const { return count == 0; }
};

// The orientation solution whose angles (each a whole number of turns from them) a joint vector's
// rotaries hold, as orient_within_limits reports it; branch -1: none (a free joint, a failure).
// The position solve takes the rotaries' cosines and sines from its terms.
struct ChosenSolution {
    const OrientationSolutions* from = nullptr;
    int branch = -1;
};

// Wraps an angle in degrees to (-180, 180].
inline double wrap180(double degrees) {
    // fmod(degrees, 360), exact, without the library call below 2^40 degrees: with n the
    // quotient truncated (one off at most), 360 n is exact, and degrees - 360 n is a multiple of
    // degrees's ulp no larger than degrees, so the subtraction is exact too; one step of 360
    // (exact for the same reason) brings it into fmod's range, the sign of degrees.
    double r = degrees;
    if (!(std::abs(degrees) < 360.0)) {
        if (std::abs(degrees) < 1099511627776.0) {
            // The truncation by conversion to an integer: std::trunc's, below 2^63, in two
            // instructions instead of its general sequence (a zero quotient cannot occur here).
            // The quotient by a product with 1/360 (rounded): below 2^32 it is off from the
            // division's by far less than one, so the truncation is one off at most, as above,
            // without the division's latency.
            r = degrees - double(static_cast<long long>(degrees * (1.0 / 360.0))) * 360.0;
            if (degrees > 0) {
                if (r < 0) r += 360.0;
                else if (r >= 360.0) r -= 360.0;
            } else {
                if (r > 0) r -= 360.0;
                else if (r <= -360.0) r += 360.0;
            }
            if (r == 0) r = std::copysign(0.0, degrees);
        } else {
            r = std::fmod(degrees, 360.0);  // NaN and infinities too
        }
    }
    if (r <= -180.0) r += 360.0;
    if (r > 180.0) r -= 360.0;
    return r;
}

}  // namespace xlate5
