// SPDX-License-Identifier: GPL-3.0-or-later
// Great-circle interpolation of unit vectors: the programmed tool axis along a move, for the
// planner's pole checks and the motion stage's samples alike. No stage; may call: Eigen.
#pragma once
#include <Eigen/Core>
#include <algorithm>
#include <cmath>

namespace xlate5 {

// Antipodal ends have no unique arc. The arc's angle is found once for the many points taken
// along one move.
struct GreatArc {
    GreatArc(const Eigen::Vector3d& from, const Eigen::Vector3d& to)
        : a(from), b(to), angle(std::acos(std::clamp(a.dot(b), -1.0, 1.0))), sn(angle < 1e-12 ? 0.0 : std::sin(angle)) {}
    Eigen::Vector3d at(double s) const {
        if (angle < 1e-12) return a;
        return ((std::sin((1 - s) * angle) / sn) * a + (std::sin(s * angle) / sn) * b).normalized();
    }
    Eigen::Vector3d a, b;
    double angle, sn;
};

}  // namespace xlate5
