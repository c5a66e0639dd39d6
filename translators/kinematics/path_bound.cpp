// SPDX-License-Identifier: GPL-3.0-or-later
// The path bound: how far, anywhere along the firmware's path between two joint vectors (every
// joint at a constant rate), the tip and the tool axis leave the chords between its ends.
#include "translators/kinematics/path_bound.hpp"

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <limits>

#include "translators/constants.hpp"
#include "translators/kinematics/scalar3.hpp"

namespace xlate5 {

using namespace kin;

JointPathBound::JointPathBound(const Machine& machine) {
    load_terms(machine);
    load_reach(machine);
    load_near_terms(machine);
}

void JointPathBound::load_terms(const Machine& machine) {
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
    split_.count = int(terms_.size());
    while (split_.rotary < split_.count && terms_[std::size_t(split_.rotary)].rotary) ++split_.rotary;
    split_.on = split_.count <= int(kMaxJoints);
    for (int k = 0; k < split_.count && split_.on; ++k) {
        split_.on = terms_[std::size_t(k)].rotary == (k < split_.rotary);
        split_.terms[k] = terms_[std::size_t(k)];
    }
}

void JointPathBound::load_reach(const Machine& machine) {
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
    arm_count_ = std::min(arm, int(kMaxJoints));  // every rotary element has an arm
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

void JointPathBound::load_near_terms(const Machine& machine) {
    std::vector<bool> counted(machine.joints.size(), false);  // each joint's reach term once
    for (std::size_t j = 0; j < machine.joints.size(); ++j)
        if (!machine.joints[j].rotary && shift_per_unit_[j] > 0) {
            near_terms_.push_back({int(j), shift_per_unit_[j], -1, shift_per_unit_[j]});
            counted[j] = true;
        }
    near_linear_ = near_terms_.size();
    for (const Term& e : terms_)
        if (e.rotary) {
            const std::size_t j = std::size_t(e.joint);
            near_terms_.push_back({e.joint, e.scale * kDeg, e.arm, counted[j] ? 0.0 : shift_per_unit_[j]});
            counted[j] = true;
        }
    covers_ = true;
    for (std::size_t j = 0; j < machine.joints.size(); ++j) covers_ = covers_ && (counted[j] || shift_per_unit_[j] == 0);
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
PathBound JointPathBound::joint_path_bound(const PathEnd& a, const double* qa, const double* qb) const {
    if (split_.on) return joint_path_bound_split(a, qa, qb);
    return joint_path_bound_general(a, qa, qb);
}

// joint_path_bound_general's sums for terms_ of rotaries alone and then linear joints alone
// (pentarod's A/C table and X/Y/Z tool chain, rw2's head), read from split_ in that order: every
// sum takes the same terms in the same order, without a test of each term's kind.
PathBound JointPathBound::joint_path_bound_split(const PathEnd& a, const double* qa, const double* qb) const {
    PathBound out;
    double rate[kMaxJoints];
    const int nr = split_.rotary, n = split_.count;
    double w = 0, s = 0, l = 0;
    for (int k = 0; k < nr; ++k) {
        const Term& e = split_.terms[k];
        rate[k] = std::abs(qb[e.joint] - qa[e.joint]) * e.scale * kDeg;
        w += rate[k];
        s += rate[k] * rate[k];
    }
    for (int k = nr; k < n; ++k) {
        const Term& e = split_.terms[k];
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
        const double ri = std::min(r, a.arm[split_.terms[k].arm] + w_after * r + l_after);
        curve += rate[k] * ri * (2 * w - rate[k]);
        w_after += rate[k];
    }
    out.tip = curve / 8.0;
    out.axis = (2 * w * w - s) / 8.0;
    return out;
}

PathBound JointPathBound::joint_path_bound_general(const PathEnd& a, const double* qa, const double* qb) const {
    PathBound out;
    double rate[kMaxJoints];  // each term's w_i (radians) or v_k (mm); the loader allows at most 5 joints, two rotary
    const std::size_t n = terms_.size();
    double w = 0, s = 0, l = 0;
    for (std::size_t k = 0; k < n; ++k) {
        const Term& e = terms_[k];
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
        const Term& e = terms_[k];
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

double JointPathBound::reach_shift(const double* qa, const double* qb) const {
    double shift = 0;
    for (std::size_t j = 0; j < shift_per_unit_.size(); ++j) shift += std::abs(qb[j] - qa[j]) * shift_per_unit_[j];
    return shift;
}

double JointPathBound::axis_path_bound(const double* qa, const double* qb) const {
    // A unit vector is at most 1 from any axis through the origin and no linear joint moves it:
    // r = 1, L = 0 for every turn, with no condition on its size (the tip's needs W < 1).
    double w = 0, s = 0;
    for (const Term& e : terms_) {
        if (!e.rotary) continue;
        const double rate = std::abs(qb[e.joint] - qa[e.joint]) * e.scale * kDeg;
        w += rate;
        s += rate * rate;
    }
    return (2 * w * w - s) / 8.0;
}

bool JointPathBound::near_end(const SolvedEnd& solved, const double* q, PathEnd& out) const {
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

}  // namespace xlate5
