// SPDX-License-Identifier: GPL-3.0-or-later
// The planner's limit policy: inside the limits, and the rotary turn chosen under them.
// What it may call: see joint_limits.hpp.
#include "translators/pipeline/joint_limits.hpp"

#include <cmath>
#include <cstdio>
#include <limits>
#include <string>

#include "translators/constants.hpp"

namespace xlate5 {

std::string joint_value_text(double v) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.3f", v);
    return buf;
}

namespace {

// inside_limits, for the functions below to inline.
inline bool inside(const Joint& J, double v) { return v >= J.min - kLimitSlack && v <= J.max + kLimitSlack; }

// orient_within_limits's shortcut for two rotaries, two solutions, no joint free, each joint's
// nearest turn taken at once (choose's first test): choose's own operations in the same order,
// without its bookkeeping. True when it placed q; anything else, a failure included, goes
// choose's general way. Apart from choose, so the usual move builds no result and pays for no
// more registers than it uses.
bool nearest_two(const Machine& machine, const std::vector<int>& rotary, const OrientationSolutions& solutions,
                 const std::vector<double>& previous, std::vector<double>& q, int& branch) {
    if (rotary.size() != 2 || solutions.count != 2) return false;
    const std::size_t j0 = std::size_t(rotary[0]), j1 = std::size_t(rotary[1]);
    const Joint& J0 = machine.joints[j0];
    const Joint& J1 = machine.joints[j1];
    const double p0 = previous[j0], p1 = previous[j1];
    const double a00 = solutions.angle[0][0], a01 = solutions.angle[0][1];
    const double a10 = solutions.angle[1][0], a11 = solutions.angle[1][1];
    auto at_once = [](const Joint& J, double prev, double nearest) {
        return !J.bounded() || (inside(J, nearest) && std::abs(nearest - prev) < 179.0);
    };
    if (std::isnan(a00) || std::isnan(a01) || std::isnan(a10) || std::isnan(a11)) return false;
    const double n00 = p0 + wrap180(a00 - p0), n01 = p1 + wrap180(a01 - p1);
    const double n10 = p0 + wrap180(a10 - p0), n11 = p1 + wrap180(a11 - p1);
    if (!(at_once(J0, p0, n00) && at_once(J1, p1, n01) && at_once(J0, p0, n10) && at_once(J1, p1, n11))) return false;
    // cost starts at 0 and adds a square (never -0): 0 + x is x.
    const double cost0 = (n00 - p0) * (n00 - p0) + (n01 - p1) * (n01 - p1);
    const double cost1 = (n10 - p0) * (n10 - p0) + (n11 - p1) * (n11 - p1);
    const double inf = std::numeric_limits<double>::infinity();
    const bool take0 = cost0 < inf;
    if (cost1 < (take0 ? cost0 : inf)) {
        q[j0] = n10, q[j1] = n11;
        branch = 1;
        return true;
    }
    if (take0) {
        q[j0] = n00, q[j1] = n01;
        branch = 0;
        return true;
    }
    return false;
}

// Of `solutions`, the turn of each rotary nearest its previous value (inside the limits when
// `limited`), and of those the solution nearest `previous` overall; `branch` its index, or -1
// when a joint of it is free.
IkResult choose(const Machine& machine, const std::vector<int>& rotary, const OrientationSolutions& solutions,
                const std::vector<double>& previous, const std::vector<double>& free_value, bool limited, std::vector<double>& q,
                int& branch) {
    const Eigen::Vector3d& axis = solutions.axis;
    if (solutions.empty()) {
        char buf[160];
        std::snprintf(buf, sizeof buf, "tool axis (%.6f, %.6f, %.6f) is out of this machine's reach", axis.x(), axis.y(), axis.z());
        return {IkStatus::Unreachable, buf};
    }
    const std::size_t n = rotary.size();
    double best_cost = std::numeric_limits<double>::infinity();
    double best[2] = {0, 0};
    bool found = false;
    int best_branch = -1;
    int failed_joint = -1;
    double failed_angle = 0;
    for (int s = 0; s < solutions.count; ++s) {
        double cand[2] = {0, 0};
        double cost = 0;
        bool ok = true, free = false;
        for (std::size_t k = 0; k < n && ok; ++k) {
            const int j = rotary[k];
            const Joint& J = machine.joints[std::size_t(j)];
            const double prev = previous[std::size_t(j)];
            const double sol = solutions.angle[s][k];
            if (std::isnan(sol)) {  // on the pole: the joint is free
                cand[k] = free_value[std::size_t(j)];
                free = true;
                continue;
            }
            // Of sol + 360 k, the turn nearest the previous angle that is inside the limits.
            // `nearest` is within 180 degrees of it and every other turn 360 degrees from it:
            // when it is inside and clearly nearer than half a turn, it is the answer (the turns
            // below would not be kept). Only at a half turn can rounding decide between two.
            const double nearest = prev + wrap180(sol - prev);
            double chosen = std::numeric_limits<double>::quiet_NaN();
            // An unbounded joint takes `nearest` too: every turn is inside, and none is nearer.
            if (!limited || !J.bounded() || (inside_limits(J, nearest) && std::abs(nearest - prev) < 179.0)) chosen = nearest;
            else for (int turn : {0, 1, -1, 2, -2}) {
                const double v = nearest + 360.0 * turn;
                if (inside_limits(J, v) && (std::isnan(chosen) || std::abs(v - prev) < std::abs(chosen - prev))) chosen = v;
            }
            if (std::isnan(chosen)) {
                ok = false;
                failed_joint = j;
                failed_angle = sol;
                break;
            }
            cand[k] = chosen;
            cost += (chosen - prev) * (chosen - prev);
        }
        if (ok && cost < best_cost) {
            best_cost = cost;
            best[0] = cand[0];
            best[1] = cand[1];
            found = true;
            best_branch = free ? -1 : s;
        }
    }
    if (!found) {
        const Joint& J = machine.joints[std::size_t(failed_joint)];
        return {IkStatus::OutOfLimits, std::string("joint ") + J.name + " would need " + joint_value_text(wrap180(failed_angle)) +
                                           " degrees, outside its limits " + joint_value_text(J.min) + " .. " + joint_value_text(J.max)};
    }
    for (std::size_t k = 0; k < n; ++k) q[std::size_t(rotary[k])] = best[k];
    branch = best_branch;
    return {};
}

}  // namespace

bool inside_limits(const Joint& J, double v) { return inside(J, v); }

bool within_limits(const Machine& machine, const std::vector<double>& q) {
    bool inside = true;
    for (std::size_t j = 0; j < machine.joints.size(); ++j) inside &= inside_limits(machine.joints[j], q[j]);
    return inside;
}

LimitBox::LimitBox(const Machine& machine) {
    for (const Joint& J : machine.joints) {
        lo_.push_back(J.min - kLimitSlack);  // inside_limits's bounds, computed as it computes them
        hi_.push_back(J.max + kLimitSlack);
    }
}

IkResult check_limits(const Machine& machine, const std::vector<double>& q) {
    // Nearly every move is inside: one pass says so (a NaN fails it too and is named below).
    if (within_limits(machine, q)) return {};
    // The rotaries first: the linear joints follow from the angles (a tilt past its limit also
    // throws X Y Z far out), so a rotary out of range is the cause to name.
    for (int pass = 0; pass < 2; ++pass) {
        for (std::size_t j = 0; j < machine.joints.size(); ++j) {
            const Joint& J = machine.joints[j];
            if (J.rotary != (pass == 0)) continue;
            if (!inside_limits(J, q[j])) {
                IkResult r{IkStatus::OutOfLimits,
                           std::string("joint ") + J.name + " would go to " + joint_value_text(q[j]) + ", outside its limits " + joint_value_text(J.min) + " .. " + joint_value_text(J.max),
                           !J.rotary};
                // An absent joint (a polar machine's Y) is held: the pose is out of reach, wherever the part is.
                if (J.absent) {
                    r.message += std::string(": the machine has no ") + J.name + " (it is held at " + joint_value_text(J.home) + ")";
                    r.absent = true;
                }
                return r;
            }
        }
    }
    return {};
}

IkResult orient_within_limits(const Machine& machine, const std::vector<int>& rotary, const OrientationSolutions& solutions,
                              const std::vector<double>& previous, const std::vector<double>& free_value, std::vector<double>& q,
                              ChosenSolution* chosen) {
    int branch = -1;
    if (nearest_two(machine, rotary, solutions, previous, q, branch)) {
        if (chosen) *chosen = {&solutions, branch};
        return {};
    }
    IkResult r = choose(machine, rotary, solutions, previous, free_value, true, q, branch);
    if (chosen) *chosen = {&solutions, r.ok() ? branch : -1};
    return r;
}

IkResult orient_within_limits_general(const Machine& machine, const std::vector<int>& rotary, const OrientationSolutions& solutions,
                                      const std::vector<double>& previous, const std::vector<double>& free_value, std::vector<double>& q) {
    int branch = -1;
    return choose(machine, rotary, solutions, previous, free_value, true, q, branch);
}

IkResult orient_on_branch(const Machine& machine, const std::vector<int>& rotary, const OrientationSolutions& solutions, int branch,
                          const std::vector<double>& previous, const std::vector<double>& free_value, std::vector<double>& q,
                          ChosenSolution* chosen) {
    if (branch < 0 || branch >= solutions.count) return {IkStatus::Unreachable, "no such orientation branch"};
    OrientationSolutions one = solutions;
    one.angle[0][0] = solutions.angle[branch][0];
    one.angle[0][1] = solutions.angle[branch][1];
    one.count = 1;
    int placed = -1;
    IkResult r = choose(machine, rotary, one, previous, free_value, true, q, placed);
    if (chosen) *chosen = {&solutions, r.ok() && placed == 0 ? branch : -1};
    return r;
}

IkResult orient_continuous(const Machine& machine, const std::vector<int>& rotary, const OrientationSolutions& solutions,
                           const std::vector<double>& previous, std::vector<double>& q) {
    int branch = -1;
    return choose(machine, rotary, solutions, previous, previous, false, q, branch);
}

}  // namespace xlate5
