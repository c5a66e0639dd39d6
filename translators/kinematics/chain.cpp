// SPDX-License-Identifier: GPL-3.0-or-later
// The general chain solver, the readable specification the fast paths (table_table.cpp,
// orientation_shortcut.cpp) are held to: the chain walk, forward kinematics, the position solve
// and the orientation solutions (Paden-Kahan subproblems 1 and 2) for any chain of the family.
#include "translators/kinematics/kinematics.hpp"

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <limits>

#include "translators/kinematics/scalar3.hpp"

namespace xlate5 {

using namespace kin;

namespace {

// Eigen's AngleAxis::toRotationMatrix, entry for entry.
inline M3 rot(const V3& axis, double degrees) {
    const double angle = degrees * kDeg;
    const double s = std::sin(angle), c = std::cos(angle);
    const V3 sa = axis * s, ca = axis * (1.0 - c);
    const double xy = ca.x * axis.y, xz = ca.x * axis.z, yz = ca.y * axis.z;
    return {ca.x * axis.x + c, xy - sa.z, xz + sa.y,
            xy + sa.z, ca.y * axis.y + c, yz - sa.x,
            xz - sa.y, yz + sa.x, ca.z * axis.z + c};
}

// Paden-Kahan subproblem 1: the angle (radians) about unit w that takes p to q is atan2(y, x)
// of these; NaN if free.
struct Subproblem1 {
    double y, x;
    bool free;
};
Subproblem1 subproblem1_terms(const Eigen::Vector3d& w, const Eigen::Vector3d& p, const Eigen::Vector3d& q) {
    const Eigen::Vector3d pp = p - w * w.dot(p);
    const Eigen::Vector3d qq = q - w * w.dot(q);
    if (pp.norm() < kFreeEps || qq.norm() < kFreeEps) return {0, 0, true};
    return {w.dot(pp.cross(qq)), pp.dot(qq), false};
}
double angle_of(const Subproblem1& t) { return t.free ? std::numeric_limits<double>::quiet_NaN() : std::atan2(t.y, t.x); }
double subproblem1(const Eigen::Vector3d& w, const Eigen::Vector3d& p, const Eigen::Vector3d& q) {
    return angle_of(subproblem1_terms(w, p, q));
}

}  // namespace

// See chain.hpp; the walk below.
std::vector<ChainLink> compile_chain(const std::vector<ChainElement>& chain) {
    std::vector<ChainLink> links;
    bool fresh = true;
    for (const auto& e : chain) {
        ChainLink l;
        l.fresh = fresh;
        l.joint = e.joint;
        for (int i = 0; i < 3; ++i) l.axis[i] = e.axis[i], l.point[i] = e.point[i];
        switch (e.kind) {
            case ChainElement::Kind::Fixed: {
                const Eigen::Matrix3d F = e.fixed.linear();
                for (int i = 0; i < 3; ++i) {
                    l.shift[i] = e.fixed.translation()[i];
                    for (int j = 0; j < 3; ++j) l.rot[i * 3 + j] = F(i, j);
                }
                const bool turns = F != Eigen::Matrix3d::Identity();
                l.shifts = e.fixed.translation() != Eigen::Vector3d::Zero();
                if (!turns && !l.shifts) continue;  // the identity (a calibration offset of 0): R, t as they are
                l.kind = turns ? ChainLink::Kind::Fixed : ChainLink::Kind::Shift;
                fresh = fresh && !turns;
                break;
            }
            case ChainElement::Kind::Linear: l.kind = ChainLink::Kind::Linear; break;
            case ChainElement::Kind::Rotary: {
                l.kind = ChainLink::Kind::Rotary;
                l.shifts = e.point != Eigen::Vector3d::Zero();  // an axis through the origin moves no point of it
                for (int k = 0; k < 3; ++k) {
                    const int i = (k + 1) % 3, j = (k + 2) % 3;
                    if (e.axis[i] == 0 && e.axis[j] == 0 && std::abs(e.axis[k]) == 1) {
                        l.kind = k == 0 ? ChainLink::Kind::RotaryX : k == 1 ? ChainLink::Kind::RotaryY : ChainLink::Kind::RotaryZ;
                        l.sign = e.axis[k];
                    }
                }
                fresh = false;
                break;
            }
        }
        links.push_back(l);
    }
    return links;
}

namespace {

// The position solve's end (both solves): the lever arms at the solution from the walk's own
// lines. The linear joints moved by `moved` carry the tip `tt` (those of the tool chain) and the
// axis lines behind them (those ahead of each line in its chain, `shifts`) along their
// directions; nothing turns. The solve is exact up to rounding (the tip is affine in the linear
// joints), which the bound's own slack covers as it does the FK's.
[[gnu::always_inline]] inline void fill_solved_end(const std::vector<SolvedEndPlan::LineShift>& shifts, const std::vector<int>& tool_linear, std::size_t n, const double* moved, V3 tt,
                     const AxisLine* lines, int count, const Eigen::Vector3d* part_dirs, const Eigen::Vector3d* tool_dirs,
                     const Eigen::Vector3d& tip, const std::vector<double>& q, Kinematics::SolvedEnd& end) {
    V3 x = tt;
    for (const int j : tool_linear) x = x + v3(tool_dirs[j]) * moved[j];
    Kinematics::PathEnd& e = end.end;
    e.lever_arm = 0;
    e.tip_slack = e.axis_slack = 0;
    for (int i = 0; i < count; ++i) {
        AxisLine line = lines[i];
        const auto& ls = shifts[std::size_t(i)];
        if (ls.linear) {
            const Eigen::Vector3d* dirs = ls.tool ? tool_dirs : part_dirs;
            for (std::size_t j = 0; j < n; ++j)
                if (ls.linear >> j & 1u) line.point = line.point + v3(dirs[j]) * moved[j];
        }
        e.arm[i] = distance_from(x, line);
        e.lever_arm = std::max(e.lever_arm, e.arm[i]);
    }
    e.pose.tip = tip;
    end.q = q;
    end.valid = true;
}

// Base -> the chain's end: rotation R and translation t. `linear_dirs`, when given, receives each
// linear joint's direction (indexed by joint); `lines` each rotary joint's axis.
//
// The shortcuts (see compile_chain) give the general products' results to the last bit: with R
// the identity, R v sums v's entries with terms 1 * v and 0 * w, which are v and zeros; a joint
// turning about +-1 times a coordinate axis k has (Eigen's formula) the rotation with c, -+s, +-s,
// c in the plane of the other two axes i, j and (1 - c) + c at (k, k), zeros elsewhere, so every
// product with it has one term that is an exact zero, and x + 0 is x. (Only the sign of a zero
// result could differ: nothing downstream divides by one or prints its sign.)
template <int k, bool kShift>
[[gnu::always_inline]] inline void turn_about_axis(double sign, double degrees, const double* point, M3& R, V3& t, bool fresh) {
    const double angle = degrees * kDeg;
    const double s = std::sin(angle), c = std::cos(angle);
    const double ss = sign * s, d = (1.0 - c) + c;
    constexpr int i = (k + 1) % 3, j = (k + 2) % 3;
    // v = point - Rj point (a point on the axis at the origin: no shift, see compile_chain)
    double v[3] = {0, 0, 0};
    if (kShift) {
        v[i] = point[i] - (c * point[i] - ss * point[j]);
        v[j] = point[j] - (ss * point[i] + c * point[j]);
        v[k] = point[k] - d * point[k];
    }
    const V3 vv{v[0], v[1], v[2]};
    if (fresh) {
        if (kShift) t = t + vv;
        double m[9] = {};
        m[i * 3 + i] = c, m[i * 3 + j] = -ss, m[j * 3 + i] = ss, m[j * 3 + j] = c, m[k * 3 + k] = d;
        R = {m[0], m[1], m[2], m[3], m[4], m[5], m[6], m[7], m[8]};
        return;
    }
    if (kShift) t = t + R * vv;
    // Columns of R Rj: R's column i times c plus column j times s, and so on.
    double r[9] = {R.xx, R.xy, R.xz, R.yx, R.yy, R.yz, R.zx, R.zy, R.zz};
    for (int row = 0; row < 3; ++row) {
        const double a = r[row * 3 + i], b = r[row * 3 + j];
        r[row * 3 + i] = a * c + b * ss;
        r[row * 3 + j] = a * -ss + b * c;
        r[row * 3 + k] *= d;
    }
    R = {r[0], r[1], r[2], r[3], r[4], r[5], r[6], r[7], r[8]};
}

// kShift false: the rotation alone (tool_axis), the same products in the same order, so R is the
// same to the last bit. kExtras false: no linear directions or axis lines asked for (the
// position solve), so the walk does not test for them at every link.
template <bool kShift, bool kExtras = kShift>
void walk_links(const std::vector<ChainLink>& chain, const double* q, M3& R, V3& t, Eigen::Vector3d* linear_dirs,
                AxisLine* lines, int* line_count) {
    using K = ChainLink::Kind;
    R = M3{1, 0, 0, 0, 1, 0, 0, 0, 1};
    t = V3{0, 0, 0};
    for (const auto& e : chain) {
        const V3 axis{e.axis[0], e.axis[1], e.axis[2]};
        const V3 point{e.point[0], e.point[1], e.point[2]};
        const bool shifts = kShift && e.shifts;
        switch (e.kind) {
            case K::Fixed: {
                const V3 shift{e.shift[0], e.shift[1], e.shift[2]};
                const M3 F{e.rot[0], e.rot[1], e.rot[2], e.rot[3], e.rot[4], e.rot[5], e.rot[6], e.rot[7], e.rot[8]};
                if (shifts) t = t + (e.fresh ? shift : R * shift);
                R = e.fresh ? F : R * F;
                break;
            }
            case K::Shift: {
                const V3 shift{e.shift[0], e.shift[1], e.shift[2]};
                if (kShift) t = t + (e.fresh ? shift : R * shift);
                break;
            }
            case K::Linear: {
                if (!kShift) break;
                const V3 d = e.fresh ? axis : R * axis;
                if (kExtras && linear_dirs) linear_dirs[e.joint] = Eigen::Vector3d(d.x, d.y, d.z);
                t = t + d * q[e.joint];
                break;
            }
            case K::Rotary:
            case K::RotaryX:
            case K::RotaryY:
            case K::RotaryZ: {
                if (kShift && kExtras && lines) lines[(*line_count)++] = {t + R * point, normalized(R * axis)};
                if (e.kind == K::RotaryX) {
                    if (shifts) turn_about_axis<0, true>(e.sign, q[e.joint], e.point, R, t, e.fresh);
                    else turn_about_axis<0, false>(e.sign, q[e.joint], e.point, R, t, e.fresh);
                } else if (e.kind == K::RotaryY) {
                    if (shifts) turn_about_axis<1, true>(e.sign, q[e.joint], e.point, R, t, e.fresh);
                    else turn_about_axis<1, false>(e.sign, q[e.joint], e.point, R, t, e.fresh);
                } else if (e.kind == K::RotaryZ) {
                    if (shifts) turn_about_axis<2, true>(e.sign, q[e.joint], e.point, R, t, e.fresh);
                    else turn_about_axis<2, false>(e.sign, q[e.joint], e.point, R, t, e.fresh);
                } else {
                    // Trans(point) * Rot(axis, q) * Trans(-point)
                    const M3 Rj = rot(axis, q[e.joint]);
                    if (shifts) t = t + (e.fresh ? point - Rj * point : R * (point - Rj * point));
                    R = e.fresh ? Rj : R * Rj;
                }
                break;
            }
        }
    }
}

void walk(const std::vector<ChainLink>& chain, const double* q, M3& R, V3& t, Eigen::Vector3d* linear_dirs,
          AxisLine* lines = nullptr, int* line_count = nullptr) {
    walk_links<true>(chain, q, R, t, linear_dirs, lines, line_count);
}

void walk_rotation(const std::vector<ChainLink>& chain, const double* q, M3& R) {
    V3 t;
    walk_links<false>(chain, q, R, t, nullptr, nullptr, nullptr);
}

// The tool axis in the part frame from the two chains' rotations (forward and tool_axis alike).
inline Eigen::Vector3d part_axis(const M3& Rp, const M3& Rt, const Eigen::Vector3d& tool) {
    const V3 axis = normalized(transposed_times(Rp, Rt * v3(tool)));
    return Eigen::Vector3d(axis.x, axis.y, axis.z);
}

}  // namespace

namespace {

// The linear joints' step dq = J^-1 (tip - current) from J's columns, as Eigen computes a fixed-size 3x3:
// the determinant as bruteforce_det3_helper sums it, the inverse from the first column's
// cofactors with one division (so the same bits as solve_position_general's). False when J is
// singular. The scalar solve's step (a two-turn table's closed form inverts its constant part at
// load instead).
[[gnu::always_inline]] inline bool jacobian_step(const V3 (&col)[3], const Eigen::Vector3d& tip, const V3& current, V3& dq) {
    const double m00 = col[0].x, m10 = col[0].y, m20 = col[0].z, m01 = col[1].x, m11 = col[1].y, m21 = col[1].z, m02 = col[2].x,
                 m12 = col[2].y, m22 = col[2].z;
    const double det = (m00 * (m11 * m22 - m12 * m21) - m01 * (m10 * m22 - m12 * m20)) + m02 * (m10 * m21 - m11 * m20);
    if (!(std::abs(det) > 1e-9)) return false;
    const double c00 = m11 * m22 - m12 * m21, c10 = m21 * m02 - m22 * m01, c20 = m01 * m12 - m02 * m11;
    const double invdet = 1.0 / ((c00 * m00 + c10 * m10) + c20 * m20);
    const M3 Ji{c00 * invdet, c10 * invdet, c20 * invdet,
                (m12 * m20 - m10 * m22) * invdet, (m22 * m00 - m20 * m02) * invdet, (m02 * m10 - m00 * m12) * invdet,
                (m10 * m21 - m11 * m20) * invdet, (m20 * m01 - m21 * m00) * invdet, (m00 * m11 - m01 * m10) * invdet};
    dq = Ji * (v3(tip) - current);
    return true;
}

// Base -> a chain's end (rotation, translation) in Eigen's types; `linear_dirs`, when given,
// receives each linear joint's direction.
void eval(const std::vector<ChainLink>& chain, const double* q, Eigen::Matrix3d& R_out, Eigen::Vector3d& t_out,
          Eigen::Vector3d* linear_dirs) {
    M3 R;
    V3 t;
    walk(chain, q, R, t, linear_dirs);
    R_out << R.xx, R.xy, R.xz, R.yx, R.yy, R.yz, R.zx, R.zy, R.zz;
    t_out = Eigen::Vector3d(t.x, t.y, t.z);
}

// The position solve's 3x3 Jacobian from the chains' linear directions; false when singular.
bool linear_jacobian(const std::vector<int>& linear, const Eigen::Matrix3d& Rp, const Eigen::Vector3d* part_dirs,
                     const Eigen::Vector3d* tool_dirs, Eigen::Matrix3d& J) {
    if (linear.size() < 3) return false;  // the loader requires three; a machine built by hand may not have them
    for (int k = 0; k < 3; ++k) {
        const std::size_t j = std::size_t(linear[std::size_t(k)]);
        J.col(k) = Rp.transpose() * (tool_dirs[j] - part_dirs[j]);
    }
    return std::abs(J.determinant()) > 1e-9;
}

}  // namespace

// The position solve's constants: its unknowns, the Jacobian when fixed, the scalar solve's plan.
PositionSolve load_position_solve(const Machine& machine, const std::vector<ChainLink>& part_links,
                                  const std::vector<ChainLink>& tool_links) {
    PositionSolve ps;
    // The position solve's Jacobian (the linear joints' directions seen from the part) depends on
    // the rotaries only through the rotations ahead of the linear joints. With none there (a part
    // chain without rotaries, no rotary before a linear joint in the tool chain: rw2's X Y Z
    // carrying the head) it is the same matrix for every pose: inverted once here, the same
    // numbers the per-call inverse would give.
    for (std::size_t j = 0; j < machine.joints.size() && ps.linear.size() < 3; ++j)
        if (!machine.joints[j].rotary) ps.linear.push_back(int(j));
    bool varies = ps.linear.size() < 3;
    for (const auto& e : machine.part_chain) varies = varies || e.kind == ChainElement::Kind::Rotary;
    bool rotary_seen = false;
    for (const auto& e : machine.tool_chain) {
        if (e.kind == ChainElement::Kind::Rotary) rotary_seen = true;
        else if (e.kind == ChainElement::Kind::Linear && rotary_seen) varies = true;
    }
    if (!varies) {
        const std::vector<double> zero(machine.joints.size(), 0.0);
        Eigen::Vector3d part_dirs[kMaxJoints], tool_dirs[kMaxJoints];
        for (std::size_t j = 0; j < machine.joints.size(); ++j) part_dirs[j].setZero(), tool_dirs[j].setZero();
        Eigen::Matrix3d Rp, Rt, J;
        Eigen::Vector3d tp, tt;
        eval(part_links, zero.data(), Rp, tp, part_dirs);
        eval(tool_links, zero.data(), Rt, tt, tool_dirs);
        if (linear_jacobian(ps.linear, Rp, part_dirs, tool_dirs, J)) {
            const Eigen::Matrix3d Ji = J.inverse();
            for (int i = 0; i < 3; ++i)
                for (int j = 0; j < 3; ++j) ps.jacobian_inverse[i * 3 + j] = Ji(i, j);
            ps.constant_jacobian = true;
        }
    }
    // The scalar solve's plan: which chain gives each unknown's direction, and a tool chain of
    // fresh linear links alone (its rotation the identity throughout: the identity times the tool
    // axis, as the walk's product makes it, once here).
    for (std::size_t k = 0; k < ps.linear.size() && k < 3; ++k)
        for (const auto* chain : {&part_links, &tool_links})
            for (const ChainLink& l : *chain)
                if (l.kind == ChainLink::Kind::Linear && l.joint == ps.linear[k]) (chain == &tool_links ? ps.cols[k].tool : ps.cols[k].part) = true;
    ps.tool_plain = true;
    for (const ChainLink& l : tool_links) ps.tool_plain = ps.tool_plain && l.kind == ChainLink::Kind::Linear && l.fresh;
    {
        const V3 up = M3{1, 0, 0, 0, 1, 0, 0, 0, 1} * v3(machine.tool_axis);
        ps.tool_up[0] = up.x, ps.tool_up[1] = up.y, ps.tool_up[2] = up.z;
    }
    return ps;
}

Eigen::Vector3d Kinematics::tool_axis(const std::vector<double>& q) const {
    if (turns_.on()) return turns_.tool_axis(q.data());
    M3 Rp, Rt;
    walk_rotation(part_links_, q.data(), Rp);
    walk_rotation(tool_links_, q.data(), Rt);
    return part_axis(Rp, Rt, machine_.tool_axis);
}

// With `lever_arm`: also the tip's largest distance from a rotary joint's axis.
Pose Kinematics::forward(const double* q, double* lever_arm, double* arms) const {
    if (turns_.on()) return turns_.forward(q, lever_arm, arms);
    M3 Rp, Rt;
    V3 tp, tt;
    AxisLine lines[kMaxJoints];  // at most 5 joints (the loader checks)
    int count = 0;
    walk(part_links_, q, Rp, tp, nullptr, lever_arm ? lines : nullptr, &count);
    walk(tool_links_, q, Rt, tt, nullptr, lever_arm ? lines : nullptr, &count);
    Pose pose;
    const V3 tip = transposed_times(Rp, tt - tp);
    pose.tip = Eigen::Vector3d(tip.x, tip.y, tip.z);
    pose.axis = part_axis(Rp, Rt, machine_.tool_axis);
    if (lever_arm) {
        // Distances are the same in every frame: measured in the base frame, the tip at tt.
        *lever_arm = 0;
        for (int i = 0; i < count; ++i) {
            const double arm = distance_from(tt, lines[i]);
            if (arms) arms[i] = arm;
            *lever_arm = std::max(*lever_arm, arm);
        }
    }
    return pose;
}

IkResult Kinematics::solve_position(const Eigen::Vector3d& tip, std::vector<double>& q, Eigen::Vector3d* axis, SolvedEnd* end,
                                    ChosenSolution chosen) const {
    if (polar_.on()) return polar_.solve(*this, tip, q, axis, end, chosen);
    // With the rotary joints fixed the tip is affine in the linear joints: one 3x3 solve is exact.
    if (position_.constant_jacobian) {
        if (end) end->valid = false;  // this path walks no axis lines: the motion stage measures the end instead
        // The same products as below in the walk's scalars (forward's tip and axis, Eigen's
        // matrix times a column), without the round trip through Eigen's matrices.
        M3 Rp, Rt;
        V3 tp, tt, current;
        walk_links<true, false>(tool_links_, q.data(), Rt, tt, nullptr, nullptr, nullptr);
        if (part_links_.empty()) {
            // The part frame is the base (Rp the identity, tp zero): the products with them give
            // tt and Rt's axis to the last bit, up to the sign of a zero (1 x + 0 y is x).
            if (axis) {
                const V3 u = normalized(Rt * v3(machine_.tool_axis));
                *axis = Eigen::Vector3d(u.x, u.y, u.z);
            }
            current = tt;
        } else {
            walk(part_links_, q.data(), Rp, tp, nullptr);
            if (axis) *axis = part_axis(Rp, Rt, machine_.tool_axis);
            current = transposed_times(Rp, tt - tp);
        }
        const double* Ji = position_.jacobian_inverse;
        const V3 dq = M3{Ji[0], Ji[1], Ji[2], Ji[3], Ji[4], Ji[5], Ji[6], Ji[7], Ji[8]} * (v3(tip) - current);
        q[std::size_t(position_.linear[0])] += dq.x;
        q[std::size_t(position_.linear[1])] += dq.y;
        q[std::size_t(position_.linear[2])] += dq.z;
        return {};
    }
    return solve_varying(tip, q, axis, end, chosen);
}

// Apart from solve_position so that its constant-Jacobian path stays as short as it was, and
// from solve_scalar so that the closed form does not pay for solve_scalar's frame.
IkResult Kinematics::solve_varying(const Eigen::Vector3d& tip, std::vector<double>& q, Eigen::Vector3d* axis, SolvedEnd* end,
                                   ChosenSolution chosen) const {
    if (!turns_.on()) return solve_scalar(tip, q, axis, end);
    return turns_.solve(tip, q, axis, end, chosen);
}


// The general solve in the walk's scalars: the same operations in the same order as
// solve_position_general's Eigen products (a matrix times a column as M3 * V3, a transposed one
// as transposed_times, normalized as Eigen's; the 3x3 determinant and inverse as Eigen writes
// them for fixed size: bruteforce_det3_helper, and the cofactors with one division), so the same
// bits; test_kinematics holds the two against each other on random machines and joints.
IkResult Kinematics::solve_scalar(const Eigen::Vector3d& tip, std::vector<double>& q, Eigen::Vector3d* axis, SolvedEnd* end) const {
    if (end) end->valid = false;
    const std::size_t n = machine_.joints.size();  // at most 5 (the loader checks)
    // Only the entries the walks write are read (see position_.cols): no zeroing.
    Eigen::Vector3d part_dirs[kMaxJoints], tool_dirs[kMaxJoints];
    const bool want_end = end && ends_.on;
    AxisLine lines[kMaxJoints];
    int count = 0;
    M3 Rp, Rt;
    V3 tp, tt, up;
    walk(part_links_, q.data(), Rp, tp, part_dirs, want_end ? lines : nullptr, &count);
    if (position_.tool_plain) {
        // Fresh linear links only: the walk's own steps for them (R stays the identity, no line),
        // and the identity times the tool axis, made once.
        tt = V3{0, 0, 0};
        for (const ChainLink& l : tool_links_) {
            const V3 d{l.axis[0], l.axis[1], l.axis[2]};
            tool_dirs[l.joint] = Eigen::Vector3d(d.x, d.y, d.z);
            tt = tt + d * q[std::size_t(l.joint)];
        }
        up = V3{position_.tool_up[0], position_.tool_up[1], position_.tool_up[2]};
    } else {
        walk(tool_links_, q.data(), Rt, tt, tool_dirs, want_end ? lines : nullptr, &count);
        up = Rt * v3(machine_.tool_axis);
    }
    if (axis || want_end) {
        const V3 u = normalized(transposed_times(Rp, up));
        if (axis) *axis = Eigen::Vector3d(u.x, u.y, u.z);
        if (want_end) end->end.pose.axis = Eigen::Vector3d(u.x, u.y, u.z);
    }
    const V3 current = transposed_times(Rp, tt - tp);
    // (linear_jacobian's refusal, after the axis as there)
    if (position_.linear.size() < 3) return singular_jacobian();
    // J's columns: Rp^T (tool direction - part direction); a direction a chain does not give is
    // zero, and x - 0 is x to the last bit (0 - x is not -x: a zero's sign).
    V3 col[3];
    for (int k = 0; k < 3; ++k) {
        const std::size_t j = std::size_t(position_.linear[std::size_t(k)]);
        V3 d = position_.cols[k].tool ? v3(tool_dirs[j]) : V3{0, 0, 0};
        if (position_.cols[k].part) d = d - v3(part_dirs[j]);
        col[k] = transposed_times(Rp, d);
    }
    V3 dq;
    if (!jacobian_step(col, tip, current, dq)) return singular_jacobian();
    q[std::size_t(position_.linear[0])] += dq.x;
    q[std::size_t(position_.linear[1])] += dq.y;
    q[std::size_t(position_.linear[2])] += dq.z;
    if (want_end) {
        double moved[kMaxJoints] = {};
        moved[position_.linear[0]] = dq.x;
        moved[position_.linear[1]] = dq.y;
        moved[position_.linear[2]] = dq.z;
        fill_solved_end(ends_.line_shifts, ends_.tool_linear, n, moved, tt, lines, count, part_dirs, tool_dirs, tip, q, *end);
    }
    return {};
}

IkResult Kinematics::solve_position_general(const Eigen::Vector3d& tip, std::vector<double>& q, Eigen::Vector3d* axis,
                                            SolvedEnd* end) const {
    if (position_.constant_jacobian) return solve_position(tip, q, axis, end);
    const std::size_t n = machine_.joints.size();  // at most 5 (the loader checks)
    Eigen::Vector3d part_dirs[kMaxJoints], tool_dirs[kMaxJoints];
    for (std::size_t j = 0; j < n; ++j) part_dirs[j].setZero(), tool_dirs[j].setZero();
    Eigen::Matrix3d Rp, Rt;
    Eigen::Vector3d tp, tt;
    // With `end` the walk also records the rotaries' axis lines (the same R and t either way).
    const bool want_end = end && ends_.on;
    if (end) end->valid = false;
    AxisLine lines[kMaxJoints];
    int count = 0;
    {
        M3 R;
        V3 t;
        walk(part_links_, q.data(), R, t, part_dirs, want_end ? lines : nullptr, &count);
        Rp << R.xx, R.xy, R.xz, R.yx, R.yy, R.yz, R.zx, R.zy, R.zz;
        tp = Eigen::Vector3d(t.x, t.y, t.z);
        walk(tool_links_, q.data(), R, t, tool_dirs, want_end ? lines : nullptr, &count);
        Rt << R.xx, R.xy, R.xz, R.yx, R.yy, R.yz, R.zx, R.zy, R.zz;
        tt = Eigen::Vector3d(t.x, t.y, t.z);
    }
    if (axis || want_end) {
        const Eigen::Vector3d u = (Rp.transpose() * (Rt * machine_.tool_axis)).normalized();
        if (axis) *axis = u;
        if (want_end) end->end.pose.axis = u;
    }
    const Eigen::Vector3d current = Rp.transpose() * (tt - tp);
    Eigen::Matrix3d J;
    if (!linear_jacobian(position_.linear, Rp, part_dirs, tool_dirs, J))
        return singular_jacobian();
    const Eigen::Vector3d dq = J.inverse() * (tip - current);  // closed-form 3x3 inverse
    for (int i = 0; i < 3; ++i) q[std::size_t(position_.linear[std::size_t(i)])] += dq[i];
    if (want_end) {
        // The lever arms at the solution from the walk's own lines: the linear joints moved by
        // dq carry the tip (those of the tool chain) and the axis lines behind them (those ahead
        // of each line in its chain) along their directions; nothing turns.
        double moved[kMaxJoints] = {};
        for (int i = 0; i < 3; ++i) moved[position_.linear[std::size_t(i)]] = dq[i];
        fill_solved_end(ends_.line_shifts, ends_.tool_linear, n, moved, v3(tt), lines, count, part_dirs, tool_dirs, tip, q, *end);
    }
    return {};
}

Kinematics::Solutions Kinematics::orientation_solutions_general(const Eigen::Vector3d& axis) const {
    const double nan = std::numeric_limits<double>::quiet_NaN();
    Solutions out;
    out.axis = axis;
    const Eigen::Vector3d u = frame_.g0.transpose() * axis.normalized();
    if (frame_.rotary.empty()) {
        if ((u - frame_.p).norm() < kReachEps) out.count = 1;
        return out;
    }
    if (frame_.rotary.size() == 1) {
        const Eigen::Vector3d& w = frame_.w[0];
        if (std::abs(w.dot(u) - w.dot(frame_.p)) > kReachEps) return out;
        const double phi = subproblem1(w, frame_.p, u);
        out.angle[0][0] = std::isnan(phi) ? nan : frame_.sign[0] * phi / kDeg;
        out.count = 1;
        return out;
    }
    const Eigen::Vector3d& w1 = frame_.w[0];
    const Eigen::Vector3d& w2 = frame_.w[1];
    const double a = w1.dot(w2);
    const double alpha = (a * w2.dot(frame_.p) - w1.dot(u)) / (a * a - 1.0);
    const double beta = (a * w1.dot(u) - w2.dot(frame_.p)) / (a * a - 1.0);
    const Eigen::Vector3d n = w1.cross(w2);
    const double gamma2 = (frame_.p.squaredNorm() - alpha * alpha - beta * beta - 2.0 * alpha * beta * a) / n.squaredNorm();
    if (gamma2 < -kReachEps * kReachEps) return out;
    const double gamma = std::sqrt(std::max(gamma2, 0.0));
    Subproblem1 first{}, first1{};
    double first_phi2 = 0, first_phi1 = 0;
    for (double s : {1.0, -1.0}) {
        const Eigen::Vector3d c = alpha * w1 + beta * w2 + s * gamma * n;
        // The second solution's tilt: when its terms are the first one's with y negated, bit for
        // bit (the machine's axes put exact zeros in the right places, as pentarod's A/C table
        // does), it is the first's negated, since atan2(-y, x) = -atan2(y, x) exactly (glibc
        // works on |y| and copies y's sign onto the result; test_kinematics holds it on random
        // values). No atan2 then.
        const Subproblem1 terms2 = subproblem1_terms(w2, frame_.p, c);
        double phi2;
        if (s < 0 && !terms2.free && !first.free && terms2.x == first.x && std::signbit(terms2.x) == std::signbit(first.x) &&
            -terms2.y == first.y && std::signbit(terms2.y) != std::signbit(first.y))
            phi2 = -first_phi2;
        else
            phi2 = angle_of(terms2);
        first = terms2;
        first_phi2 = phi2;
        // The second solution's turn: when its terms are the first one's negated (pentarod's A/C
        // table), half a turn from the first (opposite_angle). No atan2 then.
        const Subproblem1 terms1 = subproblem1_terms(w1, c, u);
        double phi1;
        if (s < 0 && !terms1.free && !first1.free && terms1.y != 0 && terms1.y == -first1.y && terms1.x == -first1.x)
            phi1 = opposite_angle(first_phi1);
        else
            phi1 = angle_of(terms1);
        first1 = terms1;
        first_phi1 = phi1;
        out.angle[out.count][0] = std::isnan(phi1) ? nan : frame_.sign[0] * phi1 / kDeg;
        out.angle[out.count][1] = std::isnan(phi2) ? nan : frame_.sign[1] * phi2 / kDeg;
        ++out.count;
        if (gamma == 0.0) break;
    }
    return out;
}

}  // namespace xlate5
