// SPDX-License-Identifier: GPL-3.0-or-later
// See table_table.hpp.
#include "translators/kinematics/table_table.hpp"

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <type_traits>

#include "translators/kinematics/scalar3.hpp"

namespace xlate5 {

using namespace kin;

namespace {

// fn(k1, k2) for TwoTurns' pattern (k1 * 3 + k2, one of the six pairs of distinct coordinate
// axes), the axes as compile-time constants (std::integral_constant): the one place the six
// instances are named. The caller has checked that the machine has the shape (pattern >= 0).
template <class Fn>
[[gnu::always_inline]] inline decltype(auto) on_two_turns(int pattern, Fn&& fn) {
    using C0 = std::integral_constant<int, 0>;
    using C1 = std::integral_constant<int, 1>;
    using C2 = std::integral_constant<int, 2>;
    switch (pattern) {
        case 0 * 3 + 1: return fn(C0{}, C1{});
        case 0 * 3 + 2: return fn(C0{}, C2{});
        case 1 * 3 + 0: return fn(C1{}, C0{});
        case 1 * 3 + 2: return fn(C1{}, C2{});
        case 2 * 3 + 0: return fn(C2{}, C0{});
        default: return fn(C2{}, C1{});  // 2 * 3 + 1
    }
}

// TwoTurns' part rotation Rp = R1 R2 (R1 about coordinate axis k1 by the first joint's angle
// times its sign, R2 about k2 likewise) as the two turns' cosines and signed sines: vectors are
// turned in closed form, two planar turns each, as Grutle (Oslo 2015) writes machine XYZ =
// R_x(A) R_z(C) p in pseudo code 4.1 (the case k1 = x, k2 = z). Not the chain walk's bits (its
// products also sum the exact zeros of each turn's matrix, and (1 - c) + c on the axis):
// test_kinematics holds the two together to rounding.
template <int k1, int k2>
struct TwoTurnRotation {
    double c1, s1, c2, s2;
    // The turn about coordinate axis k by (c, s) of v, or with kBack its inverse.
    template <int k, bool kBack>
    [[gnu::always_inline]] static V3 turn(double c, double s, const V3& v) {
        constexpr int i = (k + 1) % 3, j = (k + 2) % 3;
        double a[3] = {v.x, v.y, v.z};
        const double vi = a[i], vj = a[j];
        if (kBack) a[i] = c * vi + s * vj, a[j] = c * vj - s * vi;
        else a[i] = c * vi - s * vj, a[j] = s * vi + c * vj;
        return {a[0], a[1], a[2]};
    }
    V3 apply(const V3& v) const { return turn<k1, false>(c1, s1, turn<k2, false>(c2, s2, v)); }  // Rp v
    V3 back(const V3& v) const { return turn<k2, true>(c2, s2, turn<k1, true>(c1, s1, v)); }     // Rp^T v
};

template <int k1, int k2, class TwoTurns>
[[gnu::always_inline]] inline TwoTurnRotation<k1, k2> two_turn_rotation(const TwoTurns& f, const double* q) {
    const double a1 = q[f.j1] * kDeg, a2 = q[f.j2] * kDeg;
    return {std::cos(a1), f.sign1 * std::sin(a1), std::cos(a2), f.sign2 * std::sin(a2)};
}

// The rotation at q from the orientation solve's terms, q's two turns being solution `chosen`'s
// angles (a whole number of turns from them): cos = x / |(x, y)|, sin = y / |(x, y)| of the atan2
// that gave each. False when the solution carries no terms.
template <int k1, int k2, class TwoTurns>
[[gnu::always_inline]] inline bool two_turn_rotation_from(const TwoTurns& f, const ChosenSolution& chosen, TwoTurnRotation<k1, k2>& r) {
    if (!chosen.from || chosen.branch < 0 || !chosen.from->has_terms || f.r1 < 0) return false;
    const OrientationSolutions& s = *chosen.from;
    const double* t1 = s.terms[chosen.branch][f.r1];
    const double* t2 = s.terms[chosen.branch][f.r2];
    const double i1 = 1.0 / std::sqrt(t1[0] * t1[0] + t1[1] * t1[1]), i2 = 1.0 / std::sqrt(t2[0] * t2[0] + t2[1] * t2[1]);
    // The turn's sine is the joint's angle's times the turn's sign.
    r = {t1[1] * i1, f.sign1 * t1[0] * i1, t2[1] * i2, f.sign2 * t2[0] * i2};
    return true;
}

// The two turns' axis lines in the base frame: the first fixed, the second turned by the first.
template <int k1, int k2, class TwoTurns>
[[gnu::always_inline]] inline void two_turn_lines(const TwoTurns& f, const TwoTurnRotation<k1, k2>& r, AxisLine* lines) {
    using R = TwoTurnRotation<k1, k2>;
    lines[0] = {V3{f.line0_point[0], f.line0_point[1], f.line0_point[2]}, V3{f.line0_dir[0], f.line0_dir[1], f.line0_dir[2]}};
    lines[1] = {R::template turn<k1, false>(r.c1, r.s1, V3{f.point2[0], f.point2[1], f.point2[2]}),
                R::template turn<k1, false>(r.c1, r.s1, V3{f.axis2[0], f.axis2[1], f.axis2[2]})};
}

}  // namespace

void TwoTurns::load(const std::vector<ChainLink>& part, const std::vector<ChainLink>& tool, const std::vector<int>& unknowns,
                    const std::vector<int>& rotary, bool orient_terms, const double* up, bool want_ends) {
    using K = ChainLink::Kind;
    auto coordinate = [](K kind) { return kind == K::RotaryX ? 0 : kind == K::RotaryY ? 1 : kind == K::RotaryZ ? 2 : -1; };
    bool on = part.size() == 2 && tool.size() == 3 && unknowns.size() == 3;
    for (const ChainLink& l : tool) on = on && l.kind == K::Linear && l.fresh;
    for (std::size_t k = 0; on && k < 3; ++k) {  // each unknown moved by a tool link, by no part link
        bool in_tool = false, in_part = false;
        for (const ChainLink& l : tool) in_tool = in_tool || l.joint == unknowns[k];
        for (const ChainLink& l : part) in_part = in_part || (l.kind == K::Linear && l.joint == unknowns[k]);
        on = in_tool && !in_part;
    }
    for (std::size_t m = 0; on && m < 3; ++m)  // three distinct joints: the three unknowns
        for (std::size_t l = 0; l < m; ++l) on = on && tool[m].joint != tool[l].joint;
    if (!on) return;
    const ChainLink &a = part[0], &b = part[1];
    const int k1 = coordinate(a.kind), k2 = coordinate(b.kind);
    if (!(k1 >= 0 && k2 >= 0 && k1 != k2 && !a.shifts && !b.shifts && a.fresh && !b.fresh)) return;
    TwoTurns& f = *this;
    f.pattern = k1 * 3 + k2;
    f.j1 = a.joint, f.j2 = b.joint;
    f.sign1 = a.sign, f.sign2 = b.sign;
    for (int k = 0; k < 3; ++k) f.linear[k] = unknowns[std::size_t(k)], f.tool_up[k] = up[k];
    f.ends = want_ends;
    // The walk's first line: R the identity and t zero there.
    const M3 I{1, 0, 0, 0, 1, 0, 0, 0, 1};
    const V3 p0 = V3{0, 0, 0} + I * V3{a.point[0], a.point[1], a.point[2]};
    const V3 d0 = normalized(I * V3{a.axis[0], a.axis[1], a.axis[2]});
    f.line0_point[0] = p0.x, f.line0_point[1] = p0.y, f.line0_point[2] = p0.z;
    f.line0_dir[0] = d0.x, f.line0_dir[1] = d0.y, f.line0_dir[2] = d0.z;
    for (int i = 0; i < 3; ++i) f.point2[i] = b.point[i], f.axis2[i] = b.axis[i];
    // C: each unknown's direction (its joint's tool link) as a column.
    Eigen::Matrix3d C = Eigen::Matrix3d::Zero();
    for (std::size_t m = 0; m < 3; ++m) {
        f.tool_joint[m] = tool[m].joint;
        for (int i = 0; i < 3; ++i) f.tool_dir[m][i] = tool[m].axis[i];
        for (std::size_t k = 0; k < 3; ++k)
            if (unknowns[k] == tool[m].joint) C.col(Eigen::Index(k)) = Eigen::Vector3d(tool[m].axis[0], tool[m].axis[1], tool[m].axis[2]);
    }
    // As the general solve's test of its Jacobian Rp^T C, whose determinant is C's.
    f.singular = !(std::abs(C.determinant()) > 1e-9);
    if (orient_terms)  // the shortcut's solutions carry their atan2 terms
        for (int r = 0; r < 2 && std::size_t(r) < rotary.size(); ++r) {
            if (rotary[std::size_t(r)] == f.j1) f.r1 = r;
            if (rotary[std::size_t(r)] == f.j2) f.r2 = r;
        }
    if (f.r1 < 0 || f.r2 < 0) f.r1 = f.r2 = -1;
    if (!f.singular) {
        const Eigen::Matrix3d Ci = C.inverse();
        for (int row = 0; row < 3; ++row)
            for (int col = 0; col < 3; ++col) f.col_inv[row * 3 + col] = Ci(row, col);
    }
}

Pose TwoTurns::forward(const double* q, double* lever_arm, double* arms) const {
    return on_two_turns(pattern, [&](auto c1, auto c2) { return forward_at<decltype(c1)::value, decltype(c2)::value>(q, lever_arm, arms); });
}

Eigen::Vector3d TwoTurns::tool_axis(const double* q) const {
    // The part chain's rotation in closed form, the tool chain's the identity.
    return on_two_turns(pattern, [&](auto c1, auto c2) {
        const auto r = two_turn_rotation<decltype(c1)::value, decltype(c2)::value>(*this, q);
        const V3 u = normalized(r.back(V3{tool_up[0], tool_up[1], tool_up[2]}));
        return Eigen::Vector3d(u.x, u.y, u.z);
    });
}

IkResult TwoTurns::solve(const Eigen::Vector3d& tip, std::vector<double>& q, Eigen::Vector3d* axis, SolvedEnd* end,
                         ChosenSolution chosen) const {
    return on_two_turns(pattern, [&](auto c1, auto c2) {
        return solve_at<decltype(c1)::value, decltype(c2)::value>(tip, q, axis, end, chosen);
    });
}


// forward() for the TwoTurns shape: the tool chain's fresh linear links give the tip in the
// base frame, the part rotation's inverse takes it (and the tool axis) to the part frame.
template <int k1, int k2>
Pose TwoTurns::forward_at(const double* q, double* lever_arm, double* arms) const {
    const TwoTurns& f = *this;
    const auto r = two_turn_rotation<k1, k2>(f, q);
    V3 tt{0, 0, 0};
    for (int m = 0; m < 3; ++m) tt = tt + V3{f.tool_dir[m][0], f.tool_dir[m][1], f.tool_dir[m][2]} * q[f.tool_joint[m]];
    Pose pose;
    const V3 tip = r.back(tt);
    pose.tip = Eigen::Vector3d(tip.x, tip.y, tip.z);
    const V3 u = normalized(r.back(V3{tool_up[0], tool_up[1], tool_up[2]}));
    pose.axis = Eigen::Vector3d(u.x, u.y, u.z);
    if (lever_arm) {
        AxisLine lines[2];
        two_turn_lines(f, r, lines);
        *lever_arm = 0;
        for (int i = 0; i < 2; ++i) {
            const double arm = distance_from(tt, lines[i]);
            if (arms) arms[i] = arm;
            *lever_arm = std::max(*lever_arm, arm);
        }
    }
    return pose;
}

// The position solve for the TwoTurns shape in closed form: the tip wanted in the part frame,
// turned into the base frame (Rp tip), is where the tool chain's linear links must put it, so
// the three unknowns are C^-1 Rp tip (C: their directions, inverted at load). The general solve's
// step q += J^-1 (tip - current), with J = Rp^T C, is the same up to rounding.
template <int k1, int k2>
IkResult TwoTurns::solve_at(const Eigen::Vector3d& tip, std::vector<double>& q, Eigen::Vector3d* axis, SolvedEnd* end,
                                     ChosenSolution chosen) const {
    const TwoTurns& f = *this;
    if (end) end->valid = false;
    const bool want_end = end && ends;
    TwoTurnRotation<k1, k2> r;
    if (!two_turn_rotation_from(f, chosen, r)) r = two_turn_rotation<k1, k2>(f, q.data());
    V3 u{0, 0, 0};
    if (axis || want_end) {
        u = normalized(r.back(V3{tool_up[0], tool_up[1], tool_up[2]}));
        if (axis) *axis = Eigen::Vector3d(u.x, u.y, u.z);
    }
    if (f.singular) {
        if (want_end) end->end.pose.axis = Eigen::Vector3d(u.x, u.y, u.z);
        return singular_jacobian();
    }
    const V3 x = r.apply(v3(tip));  // the tip in the base frame: where the tool chain puts it
    const V3 lin = M3{f.col_inv[0], f.col_inv[1], f.col_inv[2], f.col_inv[3], f.col_inv[4], f.col_inv[5], f.col_inv[6], f.col_inv[7], f.col_inv[8]} * x;
    q[std::size_t(linear[0])] = lin.x;
    q[std::size_t(linear[1])] = lin.y;
    q[std::size_t(linear[2])] = lin.z;
    if (want_end) {
        // The lever arms at the solution: the tip's distance from each turn's axis line.
        AxisLine lines[2];
        two_turn_lines(f, r, lines);
        PathEnd& e = end->end;
        e.pose.axis = Eigen::Vector3d(u.x, u.y, u.z);
        e.lever_arm = 0;
        e.tip_slack = e.axis_slack = 0;
        for (int i = 0; i < 2; ++i) {
            e.arm[i] = distance_from(x, lines[i]);
            e.lever_arm = std::max(e.lever_arm, e.arm[i]);
        }
        e.pose.tip = tip;
        if (end->q.size() == q.size()) std::copy(q.begin(), q.end(), end->q.begin());  // no call for the usual case
        else end->q = q;
        end->valid = true;
    }
    return {};
}

}  // namespace xlate5
