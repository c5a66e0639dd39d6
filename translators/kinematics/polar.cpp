// SPDX-License-Identifier: GPL-3.0-or-later
// A polar machine (core-rtheta): C from the tip where the tool axis cannot say (polar.hpp).
#include "translators/kinematics/polar.hpp"

#include "translators/kinematics/kinematics.hpp"
#include <Eigen/Geometry>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <limits>
#include <type_traits>
#include "translators/constants.hpp"
#include "translators/error.hpp"
#include "translators/pipeline/joint_limits.hpp"

namespace xlate5 {

namespace {
constexpr double kDeg = kRadPerDeg;
}  // namespace

void PolarTurn::load(const Kinematics& kin, bool constant_jacobian) {
    // One absent linear joint, two rotaries: the part chain's only moving element (C) and one in
    // the tool chain (B); checked on the chain itself: at B = 0 the tool axis does not turn with C
    // (it is C's pole), and (C + 180, -B) gives the tool axis of (C, B). The position solve walks
    // a varying Jacobian (a turning part is ahead of the linear joints).
    int absent = -1, c = -1, b = -1, moving_part = 0;
    for (std::size_t j = 0; j < kin.machine().joints.size(); ++j)
        if (kin.machine().joints[j].absent) {
            if (absent >= 0) return;
            absent = int(j);
        }
    if (absent < 0 || kin.rotary_joints().size() != 2 || constant_jacobian) return;
    for (const auto& e : kin.machine().part_chain)
        if (e.kind != ChainElement::Kind::Fixed) {
            ++moving_part;
            if (e.kind == ChainElement::Kind::Rotary) c = e.joint;
        }
    if (moving_part != 1 || c < 0) return;
    b = kin.rotary_joints()[0] == c ? kin.rotary_joints()[1] : kin.rotary_joints()[0];
    std::vector<double> q = kin.machine().home_joints();
    const auto axis_at = [&](double cv, double bv) {
        q[std::size_t(c)] = cv;
        q[std::size_t(b)] = bv;
        return kin.tool_axis(q);
    };
    if ((axis_at(0, 0) - axis_at(90, 0)).norm() > 1e-12 || (axis_at(0, 20) - axis_at(180, -20)).norm() > 1e-12) return;
    on_ = true;
    c_ = c;
    b_ = b;
    absent_ = absent;
}

IkResult PolarTurn::solve(const Kinematics& kin, const Eigen::Vector3d& tip, std::vector<double>& q, Eigen::Vector3d* axis,
                          SolvedEnd* end, ChosenSolution chosen) const {
    // The rotaries as given while they leave the absent joint within its slack (every solve did so
    // before); otherwise C from the tip, and the rotaries are no longer the orientation solution's.
    const std::vector<double> start = q;
    IkResult r = kin.solve_varying(tip, q, axis, end, chosen);
    const Joint& held = kin.machine().joints[std::size_t(absent_)];
    const double y = q[std::size_t(absent_)];
    if (!r.ok() || (y >= held.min && y <= held.max)) return r;
    std::vector<double> turned = start;
    if (!turn(kin, tip, turned)) return r;
    if (IkResult again = kin.solve_varying(tip, turned, axis, end, {}); again.ok()) {
        q = std::move(turned);
        return again;
    }
    q = start;
    return kin.solve_varying(tip, q, axis, end, chosen);
}

bool PolarTurn::turn(const Kinematics& kin, const Eigen::Vector3d& tip, std::vector<double>& q) const {
    // With B held, the absent joint's solved value is a sinusoid in C: g + a cos t + b sin t for
    // C = C0 + t, read at t = 0, 90, 180. Its zeros (two, half a turn apart when the machine is
    // built true) are the angles that put the tip in the joint's plane.
    constexpr double kPolarSnapDegrees = 1e-3;  // a 5-decimal tool vector's rounding, with room
    const auto C = std::size_t(c_), B = std::size_t(b_), Y = std::size_t(absent_);
    const double c0 = q[C], home = kin.machine().joints[Y].home;
    double y[3];
    std::vector<double> t = q;
    for (int k = 0; k < 3; ++k) {
        t = q;
        t[C] = c0 + 90.0 * k;
        if (!kin.solve_varying(tip, t, nullptr, nullptr, {}).ok()) return false;
        y[k] = t[Y] - home;
    }
    const double g = 0.5 * (y[0] + y[2]), a = 0.5 * (y[0] - y[2]), s = y[1] - g, rho = std::hypot(a, s);
    if (!(rho > 1e-9) || std::abs(g) > rho) return false;  // the tip on C's axis: any C will do
    const double phi = std::atan2(s, a) / kDeg, half = std::acos(std::clamp(-g / rho, -1.0, 1.0)) / kDeg;
    // Of the angles that move the tool axis by at most the bound (a chord: exact where an acos
    // of a dot near 1 is not), the least turn that keeps the joints within their limits (else the
    // least turn); B's sign flips only where that is needed.
    const Eigen::Vector3d u = kin.tool_axis(q);
    const double chord = chord_within(kPolarSnapDegrees);
    double best_turn = std::numeric_limits<double>::infinity(), best_b = q[B];
    bool best_inside = false;
    for (const double root : {phi + half, phi - half}) {
        const double turn = wrap180(root);
        for (const double bv : {q[B], -q[B]}) {
            t = q;
            t[C] = c0 + turn;
            t[B] = bv;
            if (!((kin.tool_axis(t) - u).norm() <= chord)) continue;
            const bool inside = kin.solve_varying(tip, t, nullptr, nullptr, {}).ok() && check_limits(kin.machine(), t).ok();
            if ((inside && !best_inside) || (inside == best_inside && std::abs(turn) < std::abs(best_turn))) {
                best_turn = turn;
                best_b = bv;
                best_inside = inside;
            }
        }
    }
    if (!std::isfinite(best_turn)) return false;
    q[C] = c0 + best_turn;
    q[B] = best_b;
    return true;
}

}  // namespace xlate5
