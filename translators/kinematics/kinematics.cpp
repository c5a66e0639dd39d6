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

namespace {

// The constructor's steps (see chain.hpp for what each gives).
OrientationFrame load_orientation(const Machine& machine) {
    OrientationFrame f;
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
            if (in_g0) f.g0 = f.g0 * s.fixed;
            else acc = acc * s.fixed;
            continue;
        }
        in_g0 = false;
        f.rotary.push_back(s.joint);
        f.sign.push_back(s.sign);
        f.w.push_back((acc * s.axis).normalized());
    }
    f.p = (acc * machine.tool_axis).normalized();
    if (f.rotary.size() > 2) throw MachineError(machine.source_path + ": at most two rotary joints are supported");
    if (f.rotary.size() == 2 && f.w[0].cross(f.w[1]).norm() < 1e-9)
        throw MachineError(machine.source_path + ": the two rotary axes are parallel; such a machine cannot orient the tool");
    // R(w1, 180) fixes p (p along w1) and turns w2 into -w2 (w2 normal to w1), so
    // R(w1, t1 + 180) R(w2, -t2) p = R(w1, t1) R(w2, t2) R(w1, 180) p = R(w1, t1) R(w2, t2) p.
    f.flip = f.rotary.size() == 2 && std::abs(f.w[0].dot(f.w[1])) < 1e-9 && f.w[0].cross(f.p).norm() < 1e-9;
    return f;
}

SolvedEndPlan load_solved_ends(const Machine& machine, const std::vector<ChainLink>& part_links,
                               const std::vector<ChainLink>& tool_links, bool covers_every_shift) {
    // The solve's SolvedEnd: which linear joints move each rotary element's axis line (those
    // ahead of it in its chain), in the order forward() records the lines.
    SolvedEndPlan plan;
    unsigned seen = 0;
    bool twice = false;
    for (const auto* chain : {&part_links, &tool_links}) {
        unsigned ahead = 0;
        for (const ChainLink& l : *chain) {
            if (l.kind == ChainLink::Kind::Linear) {
                const unsigned bit = 1u << l.joint;
                twice = twice || (seen & bit) != 0;
                seen |= bit;
                ahead |= bit;
                if (chain == &tool_links) plan.tool_linear.push_back(l.joint);
            } else if (l.kind != ChainLink::Kind::Fixed && l.kind != ChainLink::Kind::Shift) {
                plan.line_shifts.push_back({chain == &tool_links, ahead});
            }
        }
    }
    plan.on = !twice && plan.line_shifts.size() <= kMaxJoints && machine.joints.size() <= kMaxJoints && covers_every_shift;
    return plan;
}

}  // namespace

Kinematics::Kinematics(const Machine& machine)
    : machine_(machine),
      part_links_(compile_chain(machine.part_chain)),
      tool_links_(compile_chain(machine.tool_chain)),
      frame_(load_orientation(machine)),
      bound_(machine),
      position_(load_position_solve(machine, part_links_, tool_links_)),
      ends_(load_solved_ends(machine, part_links_, tool_links_, bound_.covers_every_shift())) {
    if (frame_.rotary.size() == 2) orient_.load(frame_.w[0], frame_.w[1], frame_.p, frame_.g0, frame_.sign[0], frame_.sign[1]);
    turns_.load(part_links_, tool_links_, position_.linear, frame_.rotary, orient_.on(), position_.tool_up, ends_.on);
    polar_.load(*this, position_.constant_jacobian);
}

Pose Kinematics::forward(const std::vector<double>& q) const { return forward(q.data(), nullptr); }

PathEnd Kinematics::path_end(const double* q) const {
    PathEnd end;
    end.pose = forward(q, &end.lever_arm, end.arm);
    return end;
}

Kinematics::Solutions Kinematics::orientation_solutions(const Eigen::Vector3d& axis) const {
    Solutions out;
    if (!orient_.solve(axis, out)) out = orientation_solutions_general(axis);
    return out;
}

IkResult Kinematics::inverse(const Pose& pose, const std::vector<double>& previous, std::vector<double>& q) const {
    q = previous;
    if (auto r = orient_within_limits(machine_, frame_.rotary, orientation_solutions(pose.axis), previous, previous, q); !r.ok()) return r;
    if (auto r = solve_position(pose.tip, q); !r.ok()) return r;
    return check_limits(machine_, q);
}

}  // namespace xlate5
