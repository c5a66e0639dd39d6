// SPDX-License-Identifier: GPL-3.0-or-later
// The split's points. What it may call: see split_points.hpp.
#include "translators/pipeline/split_points.hpp"

#include <cmath>
#include <cstdio>
#include <cstring>

namespace xlate5 {

const Kinematics::Solutions& SolutionCache::of(const Eigen::Vector3d& axis) const {
    // Bit for bit the same axis (a signed zero counts: the solutions' angles can depend on it).
    for (const Slot& c : slots_)
        if (c.valid && std::memcmp(c.axis.data(), axis.data(), sizeof(double) * 3) == 0) return c.solutions;
    return store(axis, kin_.orientation_solutions(axis));
}

const Kinematics::Solutions& SolutionCache::store(const Eigen::Vector3d& axis, Kinematics::Solutions solutions) const {
    Slot& c = slots_[next_];
    next_ = 1 - next_;
    c.axis = axis;
    c.solutions = std::move(solutions);
    c.valid = true;
    return c.solutions;
}

SplitPoints::SplitPoints(const Kinematics& kinematics)
    : kin_(kinematics), machine_(kinematics.machine()), limits_(kinematics.machine()), solutions_(kinematics) {}

const GreatArc& SplitPoints::arc_of(const PlannedMove& mv) const {
    if (!(mv.p0.axis == arc_.a && mv.p1.axis == arc_.b)) arc_ = GreatArc(mv.p0.axis, mv.p1.axis);
    return arc_;
}

Pose SplitPoints::pose_at(const PlannedMove& mv, double s) const {
    Pose p;
    p.tip = mv.p0.tip + s * (mv.p1.tip - mv.p0.tip);
    p.axis = arc_of(mv).at(s);
    return p;
}

IkResult SplitPoints::solve_at(const PlannedMove& mv, double s, const std::vector<double>& previous, std::vector<double>& q,
                               int branch) const {
    if (mv.mode == OrientationMode::Angles) {
        const Joints& q0 = mv.q0;
        const Joints& q1 = mv.q1;
        q = previous;
        // The angles are the programmed orientation: they move linearly, as the firmware moves
        // them. Only the tip is solved for (no point on the axes' arc is needed).
        for (std::size_t j = 0; j < q.size(); ++j)
            if (machine_.joints[j].rotary) q[j] = q0[j] + s * (q1[j] - q0[j]);
        if (auto r = kin_.solve_position(mv.p0.tip + s * (mv.p1.tip - mv.p0.tip), q); !r.ok()) return r;
        return limits_.contains(q) ? IkResult{} : check_limits(machine_, q);
    }
    Target target;
    target_at(mv, s, target);
    ChosenSolution chosen;
    if (auto r = orient_at(mv, s, target, previous, q, branch, chosen); !r.ok()) return r;
    return place(target, q, chosen);
}

void SplitPoints::target_at(const PlannedMove& mv, double s, Target& target) const {
    target.pose = pose_at(mv, s);
    target.solutions = kin_.orientation_solutions(target.pose.axis);
}

IkResult SplitPoints::orient_at(const PlannedMove& mv, double s, const Target& target, const std::vector<double>& previous,
                                std::vector<double>& q, int branch, ChosenSolution& chosen) const {
    const Joints& q0 = mv.q0;
    const Joints& q1 = mv.q1;
    q = previous;
    // A free joint (axis along the tool) follows the line from its start to its end value.
    std::vector<double>& hint = lerp_;
    hint.resize(q.size());
    for (std::size_t j = 0; j < q.size(); ++j) hint[j] = q0[j] + s * (q1[j] - q0[j]);
    return branch < 0 ? orient_within_limits(machine_, kin_.rotary_joints(), target.solutions, previous, hint, q, &chosen)
                      : orient_on_branch(machine_, kin_.rotary_joints(), target.solutions, branch, previous, hint, q, &chosen);
}

IkResult SplitPoints::place(const Target& target, std::vector<double>& q, ChosenSolution chosen) const {
    if (auto rp = kin_.solve_position(target.pose.tip, q, nullptr, nullptr, chosen); !rp.ok()) return rp;
    return limits_.contains(q) ? IkResult{} : check_limits(machine_, q);
}

bool SplitPoints::same_rotaries(const std::vector<double>& a, const std::vector<double>& b) const {
    for (const int j : kin_.rotary_joints())
        if (std::memcmp(&a[std::size_t(j)], &b[std::size_t(j)], sizeof(double)) != 0) return false;
    return true;
}

IkResult SplitPoints::leaves_limits(const PlannedMove& mv, double s, const std::vector<double>& previous) const {
    if (mv.mode != OrientationMode::Vector) return {};
    std::vector<double>& cont = cont_;
    cont = previous;
    if (!orient_continuous(machine_, kin_.rotary_joints(), kin_.orientation_solutions(pose_at(mv, s).axis), previous, cont).ok()) return {};
    for (std::size_t j = 0; j < cont.size(); ++j) {
        const Joint& J = machine_.joints[j];
        if (!J.rotary || inside_limits(J, cont[j])) continue;
        char buf[200];
        std::snprintf(buf, sizeof buf, "joint %c would run past its limit %.3f at %d%% of the move (limits %.3f .. %.3f)",
                      J.name, cont[j] > J.max ? J.max : J.min, int(std::lround(s * 100)), J.min, J.max);
        return {IkStatus::OutOfLimits, buf};
    }
    return {};
}

}  // namespace xlate5
