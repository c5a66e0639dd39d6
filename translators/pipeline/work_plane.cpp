// SPDX-License-Identifier: GPL-3.0-or-later
// Tilted work planes: the Euler rotation and its inverse for a build direction.
// What it may call: see work_plane.hpp.
#include "translators/pipeline/work_plane.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>

#include <Eigen/Geometry>

namespace xlate5 {

namespace {
constexpr double kDeg = 3.14159265358979323846 / 180.0;
}

WorkPlane& StampedPlane::edit() {
    // Process-wide, so no two states' planes (of any translator, on any thread) share a stamp.
    static std::atomic<std::uint64_t> last{0};
    stamp_ = last.fetch_add(1, std::memory_order_relaxed) + 1;
    return plane_;
}

Eigen::Matrix3d euler_zxz(double i_deg, double j_deg, double k_deg) {
    using Eigen::AngleAxisd;
    return (AngleAxisd(i_deg * kDeg, Eigen::Vector3d::UnitZ()) * AngleAxisd(j_deg * kDeg, Eigen::Vector3d::UnitX()) *
            AngleAxisd(k_deg * kDeg, Eigen::Vector3d::UnitZ()))
        .toRotationMatrix();
}

Eigen::Vector3d euler_for_direction(const Eigen::Vector3d& direction) {
    // Rz(I) Rx(J) e_z = (sin I sin J, -cos I sin J, cos J).
    const Eigen::Vector3d n = direction.normalized();
    const double j = std::acos(std::clamp(n.z(), -1.0, 1.0));
    const double horizontal = std::hypot(n.x(), n.y());
    const double i = horizontal < 1e-12 ? 0.0 : std::atan2(n.x(), -n.y());
    return {i / kDeg, j / kDeg, 0.0};
}

}  // namespace xlate5
