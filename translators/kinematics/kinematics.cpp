// SPDX-License-Identifier: GPL-3.0-or-later
// The math: forward kinematics and the closed-form inverse. What it may call: see kinematics.hpp.
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
// A projected vector shorter than this leaves subproblem 1 without an answer: the joint is on
// its singular pole and keeps its previous angle.
constexpr double kFreeEps = 1e-7;
// Orientations this close (radians, squared for gamma) to the reachable set count as reachable.
constexpr double kReachEps = 1e-6;

// The chain walk below is written out in scalars: the same operations, in the same order and
// so to the last bit, as Eigen's fixed-size products (a 3x3 matrix times a column sums rows 0 and
// 1 as (a0 + a1) + a2 and row 2 as a0 + (a1 + a2); test_kinematics holds the two against each
// other), with every value in its own variable so that it stays in a register (Eigen's 3-vectors
// went through memory in part-overlapping loads and stores, which stall).
struct V3 {
    double x, y, z;
};
struct M3 {
    double xx, xy, xz, yx, yy, yz, zx, zy, zz;  // row, column
};

inline V3 v3(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }
inline V3 operator+(const V3& a, const V3& b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
inline V3 operator-(const V3& a, const V3& b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
inline V3 operator*(const V3& a, double s) { return {a.x * s, a.y * s, a.z * s}; }

inline V3 operator*(const M3& m, const V3& v) {
    return {(m.xx * v.x + m.xy * v.y) + m.xz * v.z, (m.yx * v.x + m.yy * v.y) + m.yz * v.z, m.zx * v.x + (m.zy * v.y + m.zz * v.z)};
}

inline M3 operator*(const M3& a, const M3& b) {
    const V3 c0 = a * V3{b.xx, b.yx, b.zx}, c1 = a * V3{b.xy, b.yy, b.zy}, c2 = a * V3{b.xz, b.yz, b.zz};
    return {c0.x, c1.x, c2.x, c0.y, c1.y, c2.y, c0.z, c1.z, c2.z};
}

// Eigen's normalized(): v / |v|, the squares summed (a0 + a1) + a2; a zero vector is returned as is.
inline V3 normalized(const V3& v) {
    const double n = (v.x * v.x + v.y * v.y) + v.z * v.z;
    if (!(n > 0)) return v;
    const double r = std::sqrt(n);
    return {v.x / r, v.y / r, v.z / r};
}

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
// atan2(-y, -x) from phi = atan2(y, x), y non-zero: the opposite direction, half a turn away, in
// (-pi, pi] as atan2 gives it (to an ulp of it, not atan2's own bits). Both orientation paths use
// it where a second solution's terms are the first's negated, so they stay the same to the bit.
double opposite_angle(double phi) { return phi > 0 ? phi - kPi : phi + kPi; }
double subproblem1(const Eigen::Vector3d& w, const Eigen::Vector3d& p, const Eigen::Vector3d& q) {
    return angle_of(subproblem1_terms(w, p, q));
}

// The walk's form of a chain (see ChainLink and walk below).
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

}  // namespace

double angle_of_dot(double dot) { return std::acos(std::clamp(dot, -1.0, 1.0)) * kDegPerRad; }

double turn_squared_at_most(double d) {
    if (!(d > 0)) return std::numeric_limits<double>::infinity();
    // The factor covers the division's rounding; a dot product rounded past 1 is no turn at all.
    return std::max(4.0 * (1.0 - d) / (1.0 + d) * (1.0 + 1e-12), 0.0);
}

double least_dot_below(double degrees) {
    if (!(angle_of_dot(1.0) < degrees)) return std::numeric_limits<double>::quiet_NaN();
    double least = 1.0;
    for (int i = 0; i < 64; ++i) {
        const double d = std::nextafter(least, 0.0);
        if (!(angle_of_dot(d) < degrees)) return least;
        least = d;
    }
    return std::numeric_limits<double>::quiet_NaN();
}

double chord_within(double degrees) {
    if (!(degrees > 0 && degrees < 180)) return 0.0;
    return 2.0 * std::sin(0.5 * degrees * kDeg) * (1.0 - 1e-12);
}

AngleLimit::AngleLimit(double degrees) : degrees_(degrees) {
    constexpr double kWindow = 1e-12;
    if (degrees > 0 && degrees < 180) {
        const double c = std::cos(degrees * kRadPerDeg);
        low_ = c - kWindow;
        high_ = c + kWindow;
    }
}

Kinematics::Kinematics(const Machine& machine)
    : machine_(machine), part_links_(compile_chain(machine.part_chain)), tool_links_(compile_chain(machine.tool_chain)) {
    // Orientation: u = R_part^T R_tool u0. Write it as one product of fixed rotations and joint
    // rotations, then fold the fixed ones into the axes: u' = G0^T u = R(w1,s1 q1) R(w2,s2 q2) p.
    struct Step {
        Eigen::Matrix3d fixed = Eigen::Matrix3d::Identity();
        int joint = -1;
        Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();
        double sign = 1;
    };
    std::vector<Step> steps;
    for (auto it = machine.part_chain.rbegin(); it != machine.part_chain.rend(); ++it) {
        Step s;
        if (it->kind == ChainElement::Kind::Fixed) s.fixed = it->fixed.linear().transpose();
        else if (it->kind == ChainElement::Kind::Rotary) s = Step{Eigen::Matrix3d::Identity(), it->joint, it->axis, -1.0};
        else continue;
        steps.push_back(s);
    }
    for (const auto& e : machine.tool_chain) {
        Step s;
        if (e.kind == ChainElement::Kind::Fixed) s.fixed = e.fixed.linear();
        else if (e.kind == ChainElement::Kind::Rotary) s = Step{Eigen::Matrix3d::Identity(), e.joint, e.axis, 1.0};
        else continue;
        steps.push_back(s);
    }
    Eigen::Matrix3d acc = Eigen::Matrix3d::Identity();  // fixed rotations since G0 ended
    bool in_g0 = true;
    for (const auto& s : steps) {
        if (s.joint < 0) {
            if (in_g0) g0_ = g0_ * s.fixed;
            else acc = acc * s.fixed;
            continue;
        }
        in_g0 = false;
        rotary_.push_back(s.joint);
        sign_.push_back(s.sign);
        w_.push_back((acc * s.axis).normalized());
    }
    p_ = (acc * machine.tool_axis).normalized();
    if (rotary_.size() > 2) throw MachineError(machine.source_path + ": at most two rotary joints are supported");
    if (rotary_.size() == 2 && w_[0].cross(w_[1]).norm() < 1e-9)
        throw MachineError(machine.source_path + ": the two rotary axes are parallel; such a machine cannot orient the tool");
    // R(w1, 180) fixes p (p along w1) and turns w2 into -w2 (w2 normal to w1), so
    // R(w1, t1 + 180) R(w2, -t2) p = R(w1, t1) R(w2, t2) R(w1, 180) p = R(w1, t1) R(w2, t2) p.
    flip_ = rotary_.size() == 2 && std::abs(w_[0].dot(w_[1])) < 1e-9 && w_[0].cross(p_).norm() < 1e-9;

    // orientation_solutions' shortcut: both rotary axes +-1 times a coordinate axis, exactly.
    auto coordinate_axis = [](const Eigen::Vector3d& w) {
        for (int k = 0; k < 3; ++k)
            if (std::abs(w[k]) == 1 && w[(k + 1) % 3] == 0 && w[(k + 2) % 3] == 0) return k;
        return -1;
    };
    if (rotary_.size() == 2) {
        OrientShortcut& f = orient_;
        f.i = coordinate_axis(w_[0]);
        f.j = coordinate_axis(w_[1]);
        f.on = f.i >= 0 && f.j >= 0 && f.i != f.j;
        if (f.on) {
            // The general path's constants, computed as it computes them.
            const Eigen::Vector3d& w1 = w_[0];
            const Eigen::Vector3d& w2 = w_[1];
            const Eigen::Vector3d n = w1.cross(w2);
            const Eigen::Vector3d pp2 = p_ - w2 * w2.dot(p_);
            const int k = 3 - f.i - f.j;
            f.pattern = f.i * 2 + (f.j > f.i ? f.j - 1 : f.j);  // (0,1) (0,2) (1,0) (1,2) (2,0) (2,1)
            f.w1i = w1[f.i], f.w2j = w2[f.j], f.nk = n[k];
            f.sign1 = sign_[0], f.sign2 = sign_[1];
            f.a = w1.dot(w2);
            f.den = f.a * f.a - 1.0;
            f.w2p = w2.dot(p_);
            f.aw2p = f.a * f.w2p;
            f.psq = p_.squaredNorm();
            f.nn = n.squaredNorm();
            // x / 2^m and x * 2^-m round the same real number (2^-m exact), so they agree to the bit.
            auto power_of_two = [](double v) {
                int e = 0;
                return std::isfinite(v) && std::abs(std::frexp(v, &e)) == 0.5;
            };
            f.den_inv = 1.0 / f.den, f.nn_inv = 1.0 / f.nn;
            f.exact_inv = power_of_two(f.den) && power_of_two(f.nn) && power_of_two(f.den_inv) && power_of_two(f.nn_inv);
            for (int m = 0; m < 3; ++m) f.pp2[m] = pp2[m];
            f.free2 = pp2.norm() < kFreeEps;
            f.g0_identity = g0_ == Eigen::Matrix3d::Identity();
            for (int r = 0; r < 3; ++r)
                for (int c = 0; c < 3; ++c) f.g0[r * 3 + c] = g0_(r, c);
            // |v| < kFreeEps as |v|^2 < free_sq: the square root is correctly rounded and so
            // never decreasing, and free_sq is the least double whose root reaches kFreeEps.
            double t = kFreeEps * kFreeEps;
            while (std::sqrt(t) >= kFreeEps) t = std::nextafter(t, 0.0);
            while (std::sqrt(t) < kFreeEps) t = std::nextafter(t, 1.0);
            f.free_sq = t;
            // What the shortcut takes for granted, as the general path computes it: n along k
            // alone, pp2 zero along j.
            f.on = n[f.i] == 0 && n[f.j] == 0 && pp2[f.j] == 0;
        }
    }

    // The bound's terms (see joint_path_bound): the part chain from the part back to the base,
    // then the tool chain. Each rotary element's arm index is its place in forward()'s walk (part
    // chain from the base, then the tool chain).
    int part_rotaries = 0;
    for (const auto& e : machine.part_chain) part_rotaries += e.kind == ChainElement::Kind::Rotary;
    int before = part_rotaries;  // rotary elements of the part chain ahead of the current one in the walk
    for (auto it = machine.part_chain.rbegin(); it != machine.part_chain.rend(); ++it) {
        if (it->kind == ChainElement::Kind::Fixed) continue;
        if (it->kind == ChainElement::Kind::Rotary) --before;
        terms_.push_back({it->joint, it->kind == ChainElement::Kind::Rotary, it->axis.norm(), before});
    }
    int arm = part_rotaries;
    for (const auto& e : machine.tool_chain) {
        if (e.kind == ChainElement::Kind::Fixed) continue;
        terms_.push_back({e.joint, e.kind == ChainElement::Kind::Rotary, e.axis.norm(), e.kind == ChainElement::Kind::Rotary ? arm++ : 0});
    }
    // Linear joints ahead of every rotary move the rest of the chain rigidly at a constant rate:
    // they bend nothing (see joint_path_bound).
    std::size_t lead = 0;
    while (lead < terms_.size() && !terms_[lead].rotary) ++lead;
    terms_.erase(terms_.begin(), terms_.begin() + std::ptrdiff_t(lead));
    // joint_path_bound_split's shape: the rotaries, then the linear joints alone.
    bound_count_ = int(terms_.size());
    while (bound_rotary_ < bound_count_ && terms_[std::size_t(bound_rotary_)].rotary) ++bound_rotary_;
    bound_split_ = bound_count_ <= 8;
    for (int k = 0; k < bound_count_ && bound_split_; ++k) {
        bound_split_ = terms_[std::size_t(k)].rotary == (k < bound_rotary_);
        bound_[k] = terms_[std::size_t(k)];
    }

    // The machine's reach, for a bound that needs no FK (reach()): how far the tip can be from
    // each rotary element's axis, for any joint values inside the limits (rotaries at any
    // angle). An element moves a point by at most: a fixed one its translation, a linear one its
    // axis times the joint's largest value (and a millimetre of slack past the limits), a rotary
    // one twice its point's distance from the origin. The tip seen from a tool-chain rotary is
    // the rest of the tool chain applied to the origin, less that element's point; from a
    // part-chain rotary, the whole tool chain's reach plus the part chain's up to its point.
    {
        const double inf = std::numeric_limits<double>::infinity();
        auto moves = [&](const ChainElement& e) {
            switch (e.kind) {
                case ChainElement::Kind::Fixed: return e.fixed.translation().norm();
                case ChainElement::Kind::Linear: {
                    const Joint& J = machine.joints[std::size_t(e.joint)];
                    if (!(J.min > -1e299 && J.max < 1e299)) return inf;
                    return e.axis.norm() * (std::max(std::abs(J.min), std::abs(J.max)) + 1.0);
                }
                case ChainElement::Kind::Rotary: return 2.0 * e.point.norm();
            }
            return inf;
        };
        double tool_total = 0;
        for (const auto& e : machine.tool_chain) tool_total += moves(e);
        int arm = 0;
        double before = 0;
        bool fits = true;
        for (const auto& e : machine.part_chain) {
            if (e.kind == ChainElement::Kind::Rotary) {
                if (arm < 8) reach_.arm[arm] = e.point.norm() + before + tool_total;
                fits = fits && ++arm <= 8;
            }
            before += moves(e);
        }
        for (std::size_t k = 0; k < machine.tool_chain.size(); ++k) {
            const ChainElement& e = machine.tool_chain[k];
            if (e.kind != ChainElement::Kind::Rotary) continue;
            double after = 0;
            for (std::size_t m = k + 1; m < machine.tool_chain.size(); ++m) after += moves(machine.tool_chain[m]);
            if (arm < 8) reach_.arm[arm] = e.point.norm() + after;
            fits = fits && ++arm <= 8;
        }
        for (int i = 0; i < arm && i < 8; ++i) reach_.lever_arm = std::max(reach_.lever_arm, reach_.arm[i]);
        has_reach_ = fits && std::isfinite(reach_.lever_arm);
        // Per joint: how far the tip moves per unit of it at most (mm per mm, mm per degree).
        shift_per_unit_.assign(machine.joints.size(), 0.0);
        for (const auto* chain : {&machine.part_chain, &machine.tool_chain})
            for (const auto& e : *chain) {
                if (e.kind == ChainElement::Kind::Linear) shift_per_unit_[std::size_t(e.joint)] += e.axis.norm();
                else if (e.kind == ChainElement::Kind::Rotary) shift_per_unit_[std::size_t(e.joint)] += kDeg * reach_.lever_arm;
            }
    }

    // The position solve's Jacobian (the linear joints' directions seen from the part) depends on
    // the rotaries only through the rotations ahead of the linear joints. With none there (a part
    // chain without rotaries, no rotary before a linear joint in the tool chain: rw2's X Y Z
    // carrying the head) it is the same matrix for every pose: inverted once here, the same
    // numbers the per-call inverse would give.
    for (std::size_t j = 0; j < machine.joints.size() && linear_.size() < 3; ++j)
        if (!machine.joints[j].rotary) linear_.push_back(int(j));
    bool varies = linear_.size() < 3;
    for (const auto& e : machine.part_chain) varies = varies || e.kind == ChainElement::Kind::Rotary;
    bool rotary_seen = false;
    for (const auto& e : machine.tool_chain) {
        if (e.kind == ChainElement::Kind::Rotary) rotary_seen = true;
        else if (e.kind == ChainElement::Kind::Linear && rotary_seen) varies = true;
    }
    if (!varies) {
        const std::vector<double> zero(machine.joints.size(), 0.0);
        Eigen::Vector3d part_dirs[8], tool_dirs[8];
        for (std::size_t j = 0; j < machine.joints.size(); ++j) part_dirs[j].setZero(), tool_dirs[j].setZero();
        Eigen::Matrix3d Rp, Rt, J;
        Eigen::Vector3d tp, tt;
        eval(part_links_, zero.data(), Rp, tp, part_dirs);
        eval(tool_links_, zero.data(), Rt, tt, tool_dirs);
        if (linear_jacobian(Rp, part_dirs, tool_dirs, J)) {
            const Eigen::Matrix3d Ji = J.inverse();
            for (int i = 0; i < 3; ++i)
                for (int j = 0; j < 3; ++j) jacobian_inverse_[i * 3 + j] = Ji(i, j);
            constant_jacobian_ = true;
        }
    }

    // The solve's SolvedEnd: which linear joints move each rotary element's axis line (those
    // ahead of it in its chain), in the order forward() records the lines.
    unsigned seen = 0;
    bool twice = false;
    for (const auto* chain : {&part_links_, &tool_links_}) {
        unsigned ahead = 0;
        for (const ChainLink& l : *chain) {
            if (l.kind == ChainLink::Kind::Linear) {
                const unsigned bit = 1u << l.joint;
                twice = twice || (seen & bit) != 0;
                seen |= bit;
                ahead |= bit;
                if (chain == &tool_links_) tool_linear_.push_back(l.joint);
            } else if (l.kind != ChainLink::Kind::Fixed && l.kind != ChainLink::Kind::Shift) {
                line_shifts_.push_back({chain == &tool_links_, ahead});
            }
        }
    }
    solved_ends_ = !twice && line_shifts_.size() <= 8 && machine.joints.size() <= 8;
    arm_count_ = std::min(int(line_shifts_.size()), 8);
    std::vector<bool> counted(machine.joints.size(), false);  // each joint's reach term once
    for (std::size_t j = 0; j < machine.joints.size(); ++j)
        if (!machine.joints[j].rotary && shift_per_unit_[j] > 0) {
            near_terms_.push_back({int(j), shift_per_unit_[j], -1, shift_per_unit_[j]});
            counted[j] = true;
        }
    near_linear_ = near_terms_.size();
    for (const BoundTerm& e : terms_)
        if (e.rotary) {
            const std::size_t j = std::size_t(e.joint);
            near_terms_.push_back({e.joint, e.scale * kDeg, e.arm, counted[j] ? 0.0 : shift_per_unit_[j]});
            counted[j] = true;
        }
    // near_end's growth is reach_shift's sum only when every joint that shifts the tip has a term
    // here (a rotary in no chain shifts nothing); otherwise the solve gives no ends.
    for (std::size_t j = 0; j < machine.joints.size(); ++j) solved_ends_ = solved_ends_ && (counted[j] || shift_per_unit_[j] == 0);

    // The scalar solve's plan: which chain gives each unknown's direction, and a tool chain of
    // fresh linear links alone (its rotation the identity throughout: the identity times the tool
    // axis, as the walk's product makes it, once here).
    for (std::size_t k = 0; k < linear_.size() && k < 3; ++k)
        for (const auto* chain : {&part_links_, &tool_links_})
            for (const ChainLink& l : *chain)
                if (l.kind == ChainLink::Kind::Linear && l.joint == linear_[k]) (chain == &tool_links_ ? solve_cols_[k].tool : solve_cols_[k].part) = true;
    tool_plain_ = true;
    for (const ChainLink& l : tool_links_) tool_plain_ = tool_plain_ && l.kind == ChainLink::Kind::Linear && l.fresh;
    {
        const V3 up = M3{1, 0, 0, 0, 1, 0, 0, 0, 1} * v3(machine.tool_axis);
        tool_up_[0] = up.x, tool_up_[1] = up.y, tool_up_[2] = up.z;
    }
    // The closed form's shape (see TwoTurns), checked link by link; its constants taken once.
    {
        using K = ChainLink::Kind;
        auto coordinate = [](K kind) { return kind == K::RotaryX ? 0 : kind == K::RotaryY ? 1 : kind == K::RotaryZ ? 2 : -1; };
        bool on = part_links_.size() == 2 && tool_plain_ && tool_links_.size() == 3 && linear_.size() == 3 && line_shifts_.size() == 2;
        for (std::size_t k = 0; on && k < 3; ++k) on = solve_cols_[k].tool && !solve_cols_[k].part;
        for (std::size_t m = 0; on && m < 3; ++m)  // three distinct joints: the three unknowns
            for (std::size_t l = 0; l < m; ++l) on = on && tool_links_[m].joint != tool_links_[l].joint;
        if (on) {
            const ChainLink &a = part_links_[0], &b = part_links_[1];
            const int k1 = coordinate(a.kind), k2 = coordinate(b.kind);
            on = k1 >= 0 && k2 >= 0 && k1 != k2 && !a.shifts && !b.shifts && a.fresh && !b.fresh;
            if (on) {
                TwoTurns& f = turns_;
                f.pattern = k1 * 3 + k2;
                f.j1 = a.joint, f.j2 = b.joint;
                f.sign1 = a.sign, f.sign2 = b.sign;
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
                    f.tool_joint[m] = tool_links_[m].joint;
                    for (int i = 0; i < 3; ++i) f.tool_dir[m][i] = tool_links_[m].axis[i];
                    for (std::size_t k = 0; k < 3; ++k)
                        if (linear_[k] == tool_links_[m].joint)
                            C.col(Eigen::Index(k)) = Eigen::Vector3d(tool_links_[m].axis[0], tool_links_[m].axis[1], tool_links_[m].axis[2]);
                }
                // As the general solve's test of its Jacobian Rp^T C, whose determinant is C's.
                f.singular = !(std::abs(C.determinant()) > 1e-9);
                if (orient_.on)  // the shortcut's solutions carry their atan2 terms
                    for (int r = 0; r < 2; ++r) {
                        if (rotary_[std::size_t(r)] == f.j1) f.r1 = r;
                        if (rotary_[std::size_t(r)] == f.j2) f.r2 = r;
                    }
                if (f.r1 < 0 || f.r2 < 0) f.r1 = f.r2 = -1;
                if (!f.singular) {
                    const Eigen::Matrix3d Ci = C.inverse();
                    for (int row = 0; row < 3; ++row)
                        for (int col = 0; col < 3; ++col) f.col_inv[row * 3 + col] = Ci(row, col);
                }
            }
        }
    }
    find_polar();
}

namespace {

// A rotary joint's axis in the base frame (dir unit); only the bound's lever arms use it, so it
// need not match Eigen's rounding (the bound keeps a slack).
struct AxisLine {
    V3 point, dir;
};

// The distance of x from an axis line (measured in the base frame, as forward() and the
// position solve's end measure the lever arms).
inline double distance_from(const V3& x, const AxisLine& line) {
    const V3 d = x - line.point, u = line.dir;
    const V3 off = d - u * (u.x * d.x + u.y * d.y + u.z * d.z);
    return std::sqrt(off.x * off.x + off.y * off.y + off.z * off.z);
}

// The position solve's end (both solves): the lever arms at the solution from the walk's own
// lines. The linear joints moved by `moved` carry the tip `tt` (those of the tool chain) and the
// axis lines behind them (those ahead of each line in its chain, `shifts`) along their
// directions; nothing turns. The solve is exact up to rounding (the tip is affine in the linear
// joints), which the bound's own slack covers as it does the FK's. (A template only because the
// shifts' type is Kinematics' own.)
template <class Shifts>
[[gnu::always_inline]] inline void fill_solved_end(const Shifts& shifts, const std::vector<int>& tool_linear, std::size_t n, const double* moved, V3 tt,
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

// R^T v, as Eigen sums a transposed product: every row (a0 + a1) + a2.
inline V3 transposed_times(const M3& m, const V3& v) {
    return {(m.xx * v.x + m.yx * v.y) + m.zx * v.z, (m.xy * v.x + m.yy * v.y) + m.zy * v.z, (m.xz * v.x + m.yz * v.y) + m.zz * v.z};
}


// The tool axis in the part frame from the two chains' rotations (forward and tool_axis alike).
inline Eigen::Vector3d part_axis(const M3& Rp, const M3& Rt, const Eigen::Vector3d& tool) {
    const V3 axis = normalized(transposed_times(Rp, Rt * v3(tool)));
    return Eigen::Vector3d(axis.x, axis.y, axis.z);
}

}  // namespace

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

// The error of a singular Jacobian, out of the solve's way.
[[gnu::noinline, gnu::cold]] IkResult singular_jacobian() {
    return {IkStatus::Singular, "the linear axes cannot move the tip in every direction here"};
}

}  // namespace

void Kinematics::eval(const std::vector<ChainLink>& chain, const double* q, Eigen::Matrix3d& R_out, Eigen::Vector3d& t_out,
                      Eigen::Vector3d* linear_dirs) const {
    M3 R;
    V3 t;
    walk(chain, q, R, t, linear_dirs);
    R_out << R.xx, R.xy, R.xz, R.yx, R.yy, R.yz, R.zx, R.zy, R.zz;
    t_out = Eigen::Vector3d(t.x, t.y, t.z);
}

Pose Kinematics::forward(const std::vector<double>& q) const { return forward(q.data(), nullptr); }

Eigen::Vector3d Kinematics::tool_axis(const std::vector<double>& q) const {
    // TwoTurns' shape: the part chain's rotation in closed form, the tool chain's the identity.
    if (turns_.pattern >= 0)
        return on_two_turns(turns_.pattern, [&](auto c1, auto c2) {
            const auto r = two_turn_rotation<decltype(c1)::value, decltype(c2)::value>(turns_, q.data());
            const V3 u = normalized(r.back(V3{tool_up_[0], tool_up_[1], tool_up_[2]}));
            return Eigen::Vector3d(u.x, u.y, u.z);
        });
    M3 Rp, Rt;
    walk_rotation(part_links_, q.data(), Rp);
    walk_rotation(tool_links_, q.data(), Rt);
    return part_axis(Rp, Rt, machine_.tool_axis);
}

// With `lever_arm`: also the tip's largest distance from a rotary joint's axis.
Pose Kinematics::forward(const double* q, double* lever_arm, double* arms) const {
    if (turns_.pattern >= 0)
        return on_two_turns(turns_.pattern, [&](auto c1, auto c2) {
            return forward_two_turns<decltype(c1)::value, decltype(c2)::value>(q, lever_arm, arms);
        });
    M3 Rp, Rt;
    V3 tp, tt;
    AxisLine lines[8];  // at most 5 joints (the loader checks)
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

// The bound. Seen from the part, the tip is the end point x of one serial chain (the part chain
// inverted, then the tool chain), each joint moving at a constant rate: a rotary at angular
// rate w_i (radians over the whole path), a linear joint at speed v_k. With V_i the velocity field
// of joint i (its axis carried by the joints before it), x' = sum V_i x and
// x'' = sum_i (V_i x' + sum_{j<i} [V_j, V_i] x), where for these affine fields
// |[V_j, V_i] x| <= |w_j| |V_i x| + |w_i| |V_j x|, |V_i x| <= |w_i| r_i (r_i: x's distance from
// rotary i's axis) or v_k, and the derivative of a rotary field along x' is at most |w_i| |x'|
// (zero for a linear one). Summed, with W = sum |w_i| and L = sum |v_k|:
//   |x''| <= sum_i |w_i| r_i (2 W - |w_i|) + 2 W L,
// (with one r for every axis: (2 W^2 - S) r + 2 W L, S = sum w_i^2).
// Linear joints ahead of every rotary in that chain (rw2's X Y Z carrying the head) add a
// translation at constant velocity to the whole rest of the chain: no second derivative and no
// change of any distance, so they are left out of L altogether. The distance from the chord of a
// curve whose second derivative stays below a is at most a t (1 - t) / 2 at parameter t, a / 8 at
// the middle. Along the path r_i changes at most by the speed of x relative to axis i, which only
// the joints after i give: r_i <= r_i(qa) + W_after R + L_after, with R the largest distance
// anywhere, R <= (r0 + L) / (1 - W) from the largest r0 at qa (W < 1 rad). The tool axis is a
// unit vector turned by the same rotations: r = 1, L = 0, (2 W^2 - S) / 8 with S = sum w_i^2.
Kinematics::PathEnd Kinematics::path_end(const double* q) const {
    PathEnd end;
    end.pose = forward(q, &end.lever_arm, end.arm);
    return end;
}

Kinematics::PathBound Kinematics::joint_path_bound(const PathEnd& a, const double* qa, const double* qb) const {
    if (bound_split_) return joint_path_bound_split(a, qa, qb);
    return joint_path_bound_general(a, qa, qb);
}

// joint_path_bound_general's sums for terms_ of rotaries alone and then linear joints alone
// (pentarod's A/C table and X/Y/Z tool chain, rw2's head), read from bound_ in that order: every
// sum takes the same terms in the same order, without a test of each term's kind.
Kinematics::PathBound Kinematics::joint_path_bound_split(const PathEnd& a, const double* qa, const double* qb) const {
    PathBound out;
    double rate[8];
    const int nr = bound_rotary_, n = bound_count_;
    double w = 0, s = 0, l = 0;
    for (int k = 0; k < nr; ++k) {
        const BoundTerm& e = bound_[k];
        rate[k] = std::abs(qb[e.joint] - qa[e.joint]) * e.scale * kDeg;
        w += rate[k];
        s += rate[k] * rate[k];
    }
    for (int k = nr; k < n; ++k) {
        const BoundTerm& e = bound_[k];
        rate[k] = std::abs(qb[e.joint] - qa[e.joint]) * e.scale;
        l += rate[k];
    }
    if (!(w < 0.5)) {
        out.tip = out.axis = std::numeric_limits<double>::infinity();
        return out;
    }
    const double r = (a.lever_arm + l) / (1.0 - w);
    double curve = 2 * w * l, w_after = 0, l_after = 0;
    for (int k = n; k-- > nr;) l_after += rate[k];
    for (int k = nr; k-- > 0;) {
        const double ri = std::min(r, a.arm[bound_[k].arm] + w_after * r + l_after);
        curve += rate[k] * ri * (2 * w - rate[k]);
        w_after += rate[k];
    }
    out.tip = curve / 8.0;
    out.axis = (2 * w * w - s) / 8.0;
    return out;
}

Kinematics::PathBound Kinematics::joint_path_bound_general(const PathEnd& a, const double* qa, const double* qb) const {
    PathBound out;
    double rate[8];  // each term's w_i (radians) or v_k (mm); the loader allows at most 5 joints, two rotary
    const std::size_t n = terms_.size();
    double w = 0, s = 0, l = 0;
    for (std::size_t k = 0; k < n; ++k) {
        const BoundTerm& e = terms_[k];
        const double d = std::abs(qb[e.joint] - qa[e.joint]) * e.scale;
        if (e.rotary) {
            rate[k] = d * kDeg;
            w += rate[k];
            s += rate[k] * rate[k];
        } else {
            rate[k] = d;
            l += d;
        }
    }
    if (!(w < 0.5)) {  // no useful bound for such a turn (and none at all past 1 rad)
        out.tip = out.axis = std::numeric_limits<double>::infinity();
        return out;
    }
    const double r = (a.lever_arm + l) / (1.0 - w);
    double curve = 2 * w * l, w_after = 0, l_after = 0;
    for (std::size_t k = n; k-- > 0;) {
        const BoundTerm& e = terms_[k];
        if (e.rotary) {
            const double ri = std::min(r, a.arm[e.arm] + w_after * r + l_after);
            curve += rate[k] * ri * (2 * w - rate[k]);
            w_after += rate[k];
        } else {
            l_after += rate[k];
        }
    }
    out.tip = curve / 8.0;
    out.axis = (2 * w * w - s) / 8.0;
    return out;
}

double Kinematics::reach_shift(const double* qa, const double* qb) const {
    double shift = 0;
    for (std::size_t j = 0; j < shift_per_unit_.size(); ++j) shift += std::abs(qb[j] - qa[j]) * shift_per_unit_[j];
    return shift;
}

double Kinematics::axis_path_bound(const double* qa, const double* qb) const {
    // A unit vector is at most 1 from any axis through the origin and no linear joint moves it:
    // r = 1, L = 0 for every turn, with no condition on its size (the tip's needs W < 1).
    double w = 0, s = 0;
    for (const BoundTerm& e : terms_) {
        if (!e.rotary) continue;
        const double rate = std::abs(qb[e.joint] - qa[e.joint]) * e.scale * kDeg;
        w += rate;
        s += rate * rate;
    }
    return (2 * w * w - s) / 8.0;
}

IkResult Kinematics::solve_position(const Eigen::Vector3d& tip, std::vector<double>& q, Eigen::Vector3d* axis, SolvedEnd* end,
                                    ChosenSolution chosen) const {
    if (polar_.on) return solve_polar(tip, q, axis, end, chosen);
    // With the rotary joints fixed the tip is affine in the linear joints: one 3x3 solve is exact.
    if (constant_jacobian_) {
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
        const double* Ji = jacobian_inverse_;
        const V3 dq = M3{Ji[0], Ji[1], Ji[2], Ji[3], Ji[4], Ji[5], Ji[6], Ji[7], Ji[8]} * (v3(tip) - current);
        q[std::size_t(linear_[0])] += dq.x;
        q[std::size_t(linear_[1])] += dq.y;
        q[std::size_t(linear_[2])] += dq.z;
        return {};
    }
    return solve_varying(tip, q, axis, end, chosen);
}

void Kinematics::find_polar() {
    // One absent linear joint, two rotaries: the part chain's only moving element (C) and one in
    // the tool chain (B); checked on the chain itself: at B = 0 the tool axis does not turn with C
    // (it is C's pole), and (C + 180, -B) gives the tool axis of (C, B). The position solve walks
    // a varying Jacobian (a turning part is ahead of the linear joints).
    int absent = -1, c = -1, b = -1, moving_part = 0;
    for (std::size_t j = 0; j < machine_.joints.size(); ++j)
        if (machine_.joints[j].absent) {
            if (absent >= 0) return;
            absent = int(j);
        }
    if (absent < 0 || rotary_.size() != 2 || constant_jacobian_) return;
    for (const auto& e : machine_.part_chain)
        if (e.kind != ChainElement::Kind::Fixed) {
            ++moving_part;
            if (e.kind == ChainElement::Kind::Rotary) c = e.joint;
        }
    if (moving_part != 1 || c < 0) return;
    b = rotary_[0] == c ? rotary_[1] : rotary_[0];
    std::vector<double> q = machine_.home_joints();
    const auto axis_at = [&](double cv, double bv) {
        q[std::size_t(c)] = cv;
        q[std::size_t(b)] = bv;
        return tool_axis(q);
    };
    if ((axis_at(0, 0) - axis_at(90, 0)).norm() > 1e-12 || (axis_at(0, 20) - axis_at(180, -20)).norm() > 1e-12) return;
    polar_ = {true, c, b, absent};
}

IkResult Kinematics::solve_polar(const Eigen::Vector3d& tip, std::vector<double>& q, Eigen::Vector3d* axis, SolvedEnd* end,
                                 ChosenSolution chosen) const {
    // The rotaries as given while they leave the absent joint within its slack (every solve did so
    // before); otherwise C from the tip, and the rotaries are no longer the orientation solution's.
    const std::vector<double> start = q;
    IkResult r = solve_varying(tip, q, axis, end, chosen);
    const Joint& held = machine_.joints[std::size_t(polar_.absent)];
    const double y = q[std::size_t(polar_.absent)];
    if (!r.ok() || (y >= held.min && y <= held.max)) return r;
    std::vector<double> turned = start;
    if (!polar_turn(tip, turned)) return r;
    if (IkResult again = solve_varying(tip, turned, axis, end, {}); again.ok()) {
        q = std::move(turned);
        return again;
    }
    q = start;
    return solve_varying(tip, q, axis, end, chosen);
}

bool Kinematics::polar_turn(const Eigen::Vector3d& tip, std::vector<double>& q) const {
    // With B held, the absent joint's solved value is a sinusoid in C: g + a cos t + b sin t for
    // C = C0 + t, read at t = 0, 90, 180. Its zeros (two, half a turn apart when the machine is
    // built true) are the angles that put the tip in the joint's plane.
    constexpr double kPolarSnapDegrees = 1e-3;  // a 5-decimal tool vector's rounding, with room
    const auto C = std::size_t(polar_.c), B = std::size_t(polar_.b), Y = std::size_t(polar_.absent);
    const double c0 = q[C], home = machine_.joints[Y].home;
    double y[3];
    std::vector<double> t = q;
    for (int k = 0; k < 3; ++k) {
        t = q;
        t[C] = c0 + 90.0 * k;
        if (!solve_varying(tip, t, nullptr, nullptr, {}).ok()) return false;
        y[k] = t[Y] - home;
    }
    const double g = 0.5 * (y[0] + y[2]), a = 0.5 * (y[0] - y[2]), s = y[1] - g, rho = std::hypot(a, s);
    if (!(rho > 1e-9) || std::abs(g) > rho) return false;  // the tip on C's axis: any C will do
    const double phi = std::atan2(s, a) / kDeg, half = std::acos(std::clamp(-g / rho, -1.0, 1.0)) / kDeg;
    // Of the angles that move the tool axis by at most the bound (a chord: exact where an acos
    // of a dot near 1 is not), the least turn that keeps the joints within their limits (else the
    // least turn); B's sign flips only where that is needed.
    const Eigen::Vector3d u = tool_axis(q);
    const double chord = chord_within(kPolarSnapDegrees);
    double best_turn = std::numeric_limits<double>::infinity(), best_b = q[B];
    bool best_inside = false;
    for (const double root : {phi + half, phi - half}) {
        const double turn = wrap180(root);
        for (const double bv : {q[B], -q[B]}) {
            t = q;
            t[C] = c0 + turn;
            t[B] = bv;
            if (!((tool_axis(t) - u).norm() <= chord)) continue;
            const bool inside = solve_varying(tip, t, nullptr, nullptr, {}).ok() && check_limits(machine_, t).ok();
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

// Apart from solve_position so that its constant-Jacobian path stays as short as it was, and
// from solve_scalar so that the closed form does not pay for solve_scalar's frame.
IkResult Kinematics::solve_varying(const Eigen::Vector3d& tip, std::vector<double>& q, Eigen::Vector3d* axis, SolvedEnd* end,
                                   ChosenSolution chosen) const {
    if (turns_.pattern < 0) return solve_scalar(tip, q, axis, end);
    return on_two_turns(turns_.pattern, [&](auto c1, auto c2) {
        return solve_two_turns<decltype(c1)::value, decltype(c2)::value>(tip, q, axis, end, chosen);
    });
}


// forward() for the TwoTurns shape: the tool chain's fresh linear links give the tip in the
// base frame, the part rotation's inverse takes it (and the tool axis) to the part frame.
template <int k1, int k2>
Pose Kinematics::forward_two_turns(const double* q, double* lever_arm, double* arms) const {
    const TwoTurns& f = turns_;
    const auto r = two_turn_rotation<k1, k2>(f, q);
    V3 tt{0, 0, 0};
    for (int m = 0; m < 3; ++m) tt = tt + V3{f.tool_dir[m][0], f.tool_dir[m][1], f.tool_dir[m][2]} * q[f.tool_joint[m]];
    Pose pose;
    const V3 tip = r.back(tt);
    pose.tip = Eigen::Vector3d(tip.x, tip.y, tip.z);
    const V3 u = normalized(r.back(V3{tool_up_[0], tool_up_[1], tool_up_[2]}));
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
IkResult Kinematics::solve_two_turns(const Eigen::Vector3d& tip, std::vector<double>& q, Eigen::Vector3d* axis, SolvedEnd* end,
                                     ChosenSolution chosen) const {
    const TwoTurns& f = turns_;
    if (end) end->valid = false;
    const bool want_end = end && solved_ends_;
    TwoTurnRotation<k1, k2> r;
    if (!two_turn_rotation_from(f, chosen, r)) r = two_turn_rotation<k1, k2>(f, q.data());
    V3 u{0, 0, 0};
    if (axis || want_end) {
        u = normalized(r.back(V3{tool_up_[0], tool_up_[1], tool_up_[2]}));
        if (axis) *axis = Eigen::Vector3d(u.x, u.y, u.z);
    }
    if (f.singular) {
        if (want_end) end->end.pose.axis = Eigen::Vector3d(u.x, u.y, u.z);
        return singular_jacobian();
    }
    const V3 x = r.apply(v3(tip));  // the tip in the base frame: where the tool chain puts it
    const V3 lin = M3{f.col_inv[0], f.col_inv[1], f.col_inv[2], f.col_inv[3], f.col_inv[4], f.col_inv[5], f.col_inv[6], f.col_inv[7], f.col_inv[8]} * x;
    q[std::size_t(linear_[0])] = lin.x;
    q[std::size_t(linear_[1])] = lin.y;
    q[std::size_t(linear_[2])] = lin.z;
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

// The general solve in the walk's scalars: the same operations in the same order as
// solve_position_general's Eigen products (a matrix times a column as M3 * V3, a transposed one
// as transposed_times, normalized as Eigen's; the 3x3 determinant and inverse as Eigen writes
// them for fixed size: bruteforce_det3_helper, and the cofactors with one division), so the same
// bits; test_kinematics holds the two against each other on random machines and joints.
IkResult Kinematics::solve_scalar(const Eigen::Vector3d& tip, std::vector<double>& q, Eigen::Vector3d* axis, SolvedEnd* end) const {
    if (end) end->valid = false;
    const std::size_t n = machine_.joints.size();  // at most 5 (the loader checks)
    // Only the entries the walks write are read (see solve_cols_): no zeroing.
    Eigen::Vector3d part_dirs[8], tool_dirs[8];
    const bool want_end = end && solved_ends_;
    AxisLine lines[8];
    int count = 0;
    M3 Rp, Rt;
    V3 tp, tt, up;
    walk(part_links_, q.data(), Rp, tp, part_dirs, want_end ? lines : nullptr, &count);
    if (tool_plain_) {
        // Fresh linear links only: the walk's own steps for them (R stays the identity, no line),
        // and the identity times the tool axis, made once.
        tt = V3{0, 0, 0};
        for (const ChainLink& l : tool_links_) {
            const V3 d{l.axis[0], l.axis[1], l.axis[2]};
            tool_dirs[l.joint] = Eigen::Vector3d(d.x, d.y, d.z);
            tt = tt + d * q[std::size_t(l.joint)];
        }
        up = V3{tool_up_[0], tool_up_[1], tool_up_[2]};
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
    if (linear_.size() < 3) return singular_jacobian();
    // J's columns: Rp^T (tool direction - part direction); a direction a chain does not give is
    // zero, and x - 0 is x to the last bit (0 - x is not -x: a zero's sign).
    V3 col[3];
    for (int k = 0; k < 3; ++k) {
        const std::size_t j = std::size_t(linear_[std::size_t(k)]);
        V3 d = solve_cols_[k].tool ? v3(tool_dirs[j]) : V3{0, 0, 0};
        if (solve_cols_[k].part) d = d - v3(part_dirs[j]);
        col[k] = transposed_times(Rp, d);
    }
    V3 dq;
    if (!jacobian_step(col, tip, current, dq)) return singular_jacobian();
    q[std::size_t(linear_[0])] += dq.x;
    q[std::size_t(linear_[1])] += dq.y;
    q[std::size_t(linear_[2])] += dq.z;
    if (want_end) {
        double moved[8] = {};
        moved[linear_[0]] = dq.x;
        moved[linear_[1]] = dq.y;
        moved[linear_[2]] = dq.z;
        fill_solved_end(line_shifts_, tool_linear_, n, moved, tt, lines, count, part_dirs, tool_dirs, tip, q, *end);
    }
    return {};
}

IkResult Kinematics::solve_position_general(const Eigen::Vector3d& tip, std::vector<double>& q, Eigen::Vector3d* axis,
                                            SolvedEnd* end) const {
    if (constant_jacobian_) return solve_position(tip, q, axis, end);
    const std::size_t n = machine_.joints.size();  // at most 5 (the loader checks)
    Eigen::Vector3d part_dirs[8], tool_dirs[8];
    for (std::size_t j = 0; j < n; ++j) part_dirs[j].setZero(), tool_dirs[j].setZero();
    Eigen::Matrix3d Rp, Rt;
    Eigen::Vector3d tp, tt;
    // With `end` the walk also records the rotaries' axis lines (the same R and t either way).
    const bool want_end = end && solved_ends_;
    if (end) end->valid = false;
    AxisLine lines[8];
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
    if (!linear_jacobian(Rp, part_dirs, tool_dirs, J))
        return singular_jacobian();
    const Eigen::Vector3d dq = J.inverse() * (tip - current);  // closed-form 3x3 inverse
    for (int i = 0; i < 3; ++i) q[std::size_t(linear_[std::size_t(i)])] += dq[i];
    if (want_end) {
        // The lever arms at the solution from the walk's own lines: the linear joints moved by
        // dq carry the tip (those of the tool chain) and the axis lines behind them (those ahead
        // of each line in its chain) along their directions; nothing turns.
        double moved[8] = {};
        for (int i = 0; i < 3; ++i) moved[linear_[std::size_t(i)]] = dq[i];
        fill_solved_end(line_shifts_, tool_linear_, n, moved, v3(tt), lines, count, part_dirs, tool_dirs, tip, q, *end);
    }
    return {};
}

bool Kinematics::near_end(const SolvedEnd& solved, const double* q, PathEnd& out) const {
    if (!solved.valid || !has_reach_) return false;
    const double* s = solved.q.data();
    // Along the joint-linear path from the solution to q the tip moves (relative to any axis)
    // by at most `grow` (reach_shift's sum, made in the same pass), so each arm stays within its
    // value at the solution plus that: a rotary's term is its turn times (arm + grow).
    // The linear terms come first (near_terms_), each with its reach term equal to its mm per
    // unit: one product serves both sums, in the same order as one loop over all terms.
    double grow = 0, tip = 0, axis = 0;
    const NearTerm* t = near_terms_.data();
    const NearTerm* const rotary = t + near_linear_;
    const NearTerm* const end = t + near_terms_.size();
    for (; t != rotary; ++t) {
        const double move = std::abs(q[t->joint] - s[t->joint]) * t->per_unit;  // mm
        grow += move;
        tip += move;
    }
    for (; t != end; ++t) {
        const double d = std::abs(q[t->joint] - s[t->joint]);
        grow += d * t->reach_per_unit;
        const double move = d * t->per_unit;  // radians
        tip += move * solved.end.arm[t->arm];
        axis += move;  // a unit vector turned by that angle moves at most that far
    }
    tip += axis * grow;
    out.pose = solved.end.pose;
    out.tip_slack = tip;
    out.axis_slack = axis;
    out.lever_arm = solved.end.lever_arm + grow;
    for (int i = 0; i < arm_count_; ++i) out.arm[i] = solved.end.arm[i] + grow;
    return true;
}

bool Kinematics::linear_jacobian(const Eigen::Matrix3d& Rp, const Eigen::Vector3d* part_dirs, const Eigen::Vector3d* tool_dirs,
                                 Eigen::Matrix3d& J) const {
    if (linear_.size() < 3) return false;  // the loader requires three; a machine built by hand may not have them
    for (int k = 0; k < 3; ++k) {
        const std::size_t j = std::size_t(linear_[std::size_t(k)]);
        J.col(k) = Rp.transpose() * (tool_dirs[j] - part_dirs[j]);
    }
    return std::abs(J.determinant()) > 1e-9;
}

Kinematics::Solutions Kinematics::orientation_solutions(const Eigen::Vector3d& axis) const {
    Solutions out;
    if (!orientation_shortcut(axis, out)) out = orientation_solutions_general(axis);
    return out;
}

bool Kinematics::orientation_shortcut(const Eigen::Vector3d& axis, Solutions& out) const {
    if (!orient_.on) return false;
    // The general path below with the rotary axes +-1 times coordinate axes i and j (see
    // OrientShortcut): every product with one of their zero entries is left out, and with it every
    // term that is zero for any finite input (a projection's component along the axis it is
    // projected off). A sum that keeps one non-zero term is then that term to the last bit; only
    // a sum of zeros could differ, in the sign of its zero, and a zero's sign changes nothing but
    // other zeros' signs here (no division by a value that can be zero) until an atan2 takes it
    // as y (x's sign matters only when y is zero). So where an atan2's y comes out zero, a joint
    // is free, the input is not a finite non-zero vector or the axis is on a pole (one solution),
    // all rare, the general path answers instead.
    const OrientShortcut& f = orient_;
    const double x = axis.x(), y = axis.y(), z = axis.z();
    const double sq = (x * x + y * y) + z * z;  // axis.normalized()
    if (!(sq > 0 && sq <= std::numeric_limits<double>::max())) return false;
    const double r = std::sqrt(sq);
    double u[3] = {x / r, y / r, z / r};
    if (!f.g0_identity) {  // u = g0^T v; with g0 the identity, each row's one term 1 * v
        const V3 t = transposed_times(M3{f.g0[0], f.g0[1], f.g0[2], f.g0[3], f.g0[4], f.g0[5], f.g0[6], f.g0[7], f.g0[8]}, V3{u[0], u[1], u[2]});
        u[0] = t.x, u[1] = t.y, u[2] = t.z;
    }
    // The atan2 terms (y, x) of each branch's phi1 and phi2: t[0..3] branch 1, t[4..7] branch 2;
    // false where the general path must answer.
    double t[8] = {};  // (set before every use: the zeros only tell the compiler so)
    int status = 0;  // 0: both branches, 1: unreachable, 2: the general path
    auto terms = [&](auto ci, auto cj) {
        constexpr int i = decltype(ci)::value, j = decltype(cj)::value, k = 3 - i - j;
        constexpr int i1 = (i + 1) % 3, i2 = (i + 2) % 3, j1 = (j + 1) % 3, j2 = (j + 2) % 3;
        const double w1u = f.w1i * u[i];  // w1 . u
        const double na = f.aw2p - w1u, nb = f.a * w1u - f.w2p;
        double alpha, beta, gamma2;
        if (f.exact_inv) {  // the quotients below as products, to the bit (see OrientShortcut)
            alpha = na * f.den_inv, beta = nb * f.den_inv;
            gamma2 = (f.psq - alpha * alpha - beta * beta - 2.0 * alpha * beta * f.a) * f.nn_inv;
        } else {
            alpha = na / f.den, beta = nb / f.den;
            gamma2 = (f.psq - alpha * alpha - beta * beta - 2.0 * alpha * beta * f.a) / f.nn;
        }
        if (gamma2 < -kReachEps * kReachEps) return void(status = 1);
        const double gamma = std::sqrt(std::max(gamma2, 0.0));
        if (gamma == 0.0) return void(status = 2);
        // c = alpha w1 + beta w2 + s gamma n: one term per component.
        const double ci_ = alpha * f.w1i, cj_ = beta * f.w2j, ck = gamma * f.nk, ck2 = (-1.0 * gamma) * f.nk;
        // Subproblem 1 about w2 takes p to c: p projected off w2 is the constant pp2 (zero along
        // j), c's projection is c less its j component. About w1, c to u: c and u less their i
        // components.
        const double q2 = ci_ * ci_ + ck * ck, q2b = ci_ * ci_ + ck2 * ck2;
        const double p1 = cj_ * cj_ + ck * ck, p1b = cj_ * cj_ + ck2 * ck2;
        const double q1 = u[j] * u[j] + u[k] * u[k];
        if (f.free2 || !(std::min(std::min(q2, q2b), std::min(std::min(p1, p1b), q1)) >= f.free_sq)) return void(status = 2);
        for (int b = 0; b < 2; ++b) {
            double c[3];
            c[i] = ci_, c[j] = cj_, c[k] = b == 0 ? ck : ck2;
            t[4 * b + 0] = f.w1i * (c[i1] * u[i2] - c[i2] * u[i1]);
            t[4 * b + 1] = c[i1] * u[i1] + c[i2] * u[i2];
            t[4 * b + 2] = f.w2j * (f.pp2[j1] * c[j2] - f.pp2[j2] * c[j1]);
            t[4 * b + 3] = f.pp2[j1] * c[j1] + f.pp2[j2] * c[j2];
        }
        if (t[0] == 0 || t[2] == 0 || t[4] == 0 || t[6] == 0) status = 2;
    };
    using std::integral_constant;
    switch (f.pattern) {
        case 0: terms(integral_constant<int, 0>{}, integral_constant<int, 1>{}); break;
        case 1: terms(integral_constant<int, 0>{}, integral_constant<int, 2>{}); break;
        case 2: terms(integral_constant<int, 1>{}, integral_constant<int, 0>{}); break;
        case 3: terms(integral_constant<int, 1>{}, integral_constant<int, 2>{}); break;
        case 4: terms(integral_constant<int, 2>{}, integral_constant<int, 0>{}); break;
        default: terms(integral_constant<int, 2>{}, integral_constant<int, 1>{}); break;
    }
    if (status == 2) return false;
    out.axis = axis;
    out.count = 0;
    if (status == 1) return true;  // out of reach
    // The second tilt from the first when its terms are the first's with y negated (as in the
    // general path below).
    const double phi1 = std::atan2(t[0], t[1]), phi2 = std::atan2(t[2], t[3]);
    // (t[0] is not zero here.)
    const double phi1b = t[4] == -t[0] && t[5] == -t[1] ? opposite_angle(phi1) : std::atan2(t[4], t[5]);
    const bool odd = t[7] == t[3] && std::signbit(t[7]) == std::signbit(t[3]) && -t[6] == t[2] && std::signbit(t[6]) != std::signbit(t[2]);
    const double phi2b = odd ? -phi2 : std::atan2(t[6], t[7]);
    out.angle[0][0] = f.sign1 * phi1 / kDeg;
    out.angle[0][1] = f.sign2 * phi2 / kDeg;
    out.angle[1][0] = f.sign1 * phi1b / kDeg;
    out.angle[1][1] = f.sign2 * phi2b / kDeg;
    out.count = 2;
    out.has_terms = true;
    // (The angle is sign * atan2(y, x), so atan2(sign * y, x): the sign is +-1.)
    for (int b = 0; b < 2; ++b)
        for (int r = 0; r < 2; ++r) out.terms[b][r][0] = (r == 0 ? f.sign1 : f.sign2) * t[4 * b + 2 * r], out.terms[b][r][1] = t[4 * b + 2 * r + 1];
    return true;
}

Kinematics::Solutions Kinematics::orientation_solutions_general(const Eigen::Vector3d& axis) const {
    const double nan = std::numeric_limits<double>::quiet_NaN();
    Solutions out;
    out.axis = axis;
    const Eigen::Vector3d u = g0_.transpose() * axis.normalized();
    if (rotary_.empty()) {
        if ((u - p_).norm() < kReachEps) out.count = 1;
        return out;
    }
    if (rotary_.size() == 1) {
        const Eigen::Vector3d& w = w_[0];
        if (std::abs(w.dot(u) - w.dot(p_)) > kReachEps) return out;
        const double phi = subproblem1(w, p_, u);
        out.angle[0][0] = std::isnan(phi) ? nan : sign_[0] * phi / kDeg;
        out.count = 1;
        return out;
    }
    const Eigen::Vector3d& w1 = w_[0];
    const Eigen::Vector3d& w2 = w_[1];
    const double a = w1.dot(w2);
    const double alpha = (a * w2.dot(p_) - w1.dot(u)) / (a * a - 1.0);
    const double beta = (a * w1.dot(u) - w2.dot(p_)) / (a * a - 1.0);
    const Eigen::Vector3d n = w1.cross(w2);
    const double gamma2 = (p_.squaredNorm() - alpha * alpha - beta * beta - 2.0 * alpha * beta * a) / n.squaredNorm();
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
        const Subproblem1 terms2 = subproblem1_terms(w2, p_, c);
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
        out.angle[out.count][0] = std::isnan(phi1) ? nan : sign_[0] * phi1 / kDeg;
        out.angle[out.count][1] = std::isnan(phi2) ? nan : sign_[1] * phi2 / kDeg;
        ++out.count;
        if (gamma == 0.0) break;
    }
    return out;
}

IkResult Kinematics::inverse(const Pose& pose, const std::vector<double>& previous, std::vector<double>& q) const {
    q = previous;
    if (auto r = orient_within_limits(machine_, rotary_, orientation_solutions(pose.axis), previous, previous, q); !r.ok()) return r;
    if (auto r = solve_position(pose.tip, q); !r.ok()) return r;
    return check_limits(machine_, q);
}

}  // namespace xlate5
