// SPDX-License-Identifier: GPL-3.0-or-later
// The face's loading (the constructor's steps, each fast path chosen here once) and inverse().
// What it may call: see kinematics.hpp.
#include "translators/kinematics/kinematics.hpp"

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <limits>
#include <type_traits>

#include "translators/constants.hpp"
#include "translators/error.hpp"
#include "translators/kinematics/scalar3.hpp"
#include "translators/pipeline/joint_limits.hpp"

namespace xlate5 {

using namespace kin;

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
    load_orientation(machine);
    if (rotary_.size() == 2) orient_.load(w_[0], w_[1], p_, g0_, sign_[0], sign_[1]);
    load_bound_terms(machine);
    load_reach(machine);
    load_position_solve(machine);
    load_solved_ends(machine);
    turns_.load(part_links_, tool_links_, linear_, rotary_, orient_.on(), tool_up_, solved_ends_);
    find_polar();
}

void Kinematics::load_orientation(const Machine& machine) {
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

    if (rotary_.size() == 2) orient_.load(w_[0], w_[1], p_, g0_, sign_[0], sign_[1]);
}

void Kinematics::load_bound_terms(const Machine& machine) {
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
    bound_split_ = bound_count_ <= int(kMaxJoints);
    for (int k = 0; k < bound_count_ && bound_split_; ++k) {
        bound_split_ = terms_[std::size_t(k)].rotary == (k < bound_rotary_);
        bound_[k] = terms_[std::size_t(k)];
    }
}

void Kinematics::load_reach(const Machine& machine) {
    // The machine's reach, for a bound that needs no FK (reach()): how far the tip can be from
    // each rotary element's axis, for any joint values inside the limits (rotaries at any
    // angle). An element moves a point by at most: a fixed one its translation, a linear one its
    // axis times the joint's largest value (and a millimetre of slack past the limits), a rotary
    // one twice its point's distance from the origin. The tip seen from a tool-chain rotary is
    // the rest of the tool chain applied to the origin, less that element's point; from a
    // part-chain rotary, the whole tool chain's reach plus the part chain's up to its point.
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
            if (arm < int(kMaxJoints)) reach_.arm[arm] = e.point.norm() + before + tool_total;
            fits = fits && ++arm <= int(kMaxJoints);
        }
        before += moves(e);
    }
    for (std::size_t k = 0; k < machine.tool_chain.size(); ++k) {
        const ChainElement& e = machine.tool_chain[k];
        if (e.kind != ChainElement::Kind::Rotary) continue;
        double after = 0;
        for (std::size_t m = k + 1; m < machine.tool_chain.size(); ++m) after += moves(machine.tool_chain[m]);
        if (arm < int(kMaxJoints)) reach_.arm[arm] = e.point.norm() + after;
        fits = fits && ++arm <= int(kMaxJoints);
    }
    for (int i = 0; i < arm && i < int(kMaxJoints); ++i) reach_.lever_arm = std::max(reach_.lever_arm, reach_.arm[i]);
    has_reach_ = fits && std::isfinite(reach_.lever_arm);
    // Per joint: how far the tip moves per unit of it at most (mm per mm, mm per degree).
    shift_per_unit_.assign(machine.joints.size(), 0.0);
    for (const auto* chain : {&machine.part_chain, &machine.tool_chain})
        for (const auto& e : *chain) {
            if (e.kind == ChainElement::Kind::Linear) shift_per_unit_[std::size_t(e.joint)] += e.axis.norm();
            else if (e.kind == ChainElement::Kind::Rotary) shift_per_unit_[std::size_t(e.joint)] += kDeg * reach_.lever_arm;
        }
}

// The position solve's constants: its unknowns, the Jacobian when fixed, the scalar solve's plan.
void Kinematics::load_position_solve(const Machine& machine) {
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
        Eigen::Vector3d part_dirs[kMaxJoints], tool_dirs[kMaxJoints];
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
}

void Kinematics::load_solved_ends(const Machine& machine) {
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
    solved_ends_ = !twice && line_shifts_.size() <= kMaxJoints && machine.joints.size() <= kMaxJoints;
    arm_count_ = std::min(int(line_shifts_.size()), int(kMaxJoints));
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
}

Pose Kinematics::forward(const std::vector<double>& q) const { return forward(q.data(), nullptr); }

Kinematics::Solutions Kinematics::orientation_solutions(const Eigen::Vector3d& axis) const {
    Solutions out;
    if (!orientation_shortcut(axis, out)) out = orientation_solutions_general(axis);
    return out;
}

bool Kinematics::orientation_shortcut(const Eigen::Vector3d& axis, Solutions& out) const {
    return orient_.solve(axis, out);
}

IkResult Kinematics::inverse(const Pose& pose, const std::vector<double>& previous, std::vector<double>& q) const {
    q = previous;
    if (auto r = orient_within_limits(machine_, rotary_, orientation_solutions(pose.axis), previous, previous, q); !r.ok()) return r;
    if (auto r = solve_position(pose.tip, q); !r.ok()) return r;
    return check_limits(machine_, q);
}

}  // namespace xlate5
