// SPDX-License-Identifier: GPL-3.0-or-later
// The path bound: how far, anywhere along the firmware's path between two joint vectors (every
// joint at a constant rate), the tip and the tool axis leave the chords between its ends.
#include "translators/kinematics/kinematics.hpp"

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <limits>

#include "translators/kinematics/scalar3.hpp"

namespace xlate5 {

using namespace kin;

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
    double rate[kMaxJoints];
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
    double rate[kMaxJoints];  // each term's w_i (radians) or v_k (mm); the loader allows at most 5 joints, two rotary
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

}  // namespace xlate5
