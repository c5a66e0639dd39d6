// SPDX-License-Identifier: GPL-3.0-or-later
// The collision stage's motion bounds (docs/machines.md, "Bodies"): how far each body may move
// over a step of the sweep, the boxes that hold it over the step, and the tests they allow
// (below the tool, apart from a box). Builds on collide_bodies.hpp.
#pragma once
#include <fcl/math/bv/AABB.h>
#include <fcl/math/bv/OBB.h>

#include <cmath>
#include <vector>

#include "translators/pipeline/collide_bodies.hpp"

namespace xlate5::collision_parts {

struct CollideBounds : CollideBodies {
    using CollideBodies::CollideBodies;

    // How far any point of a sphere of radius R about `centre` (base frame) carried by the tool
    // may move in the part frame over the joint change dq, from snapshot s on (docs/machines.md,
    // "Bodies"). Loose (the linear joints' travel and the rotaries' arms add up although the
    // kinematics makes them cancel at the tip): it only bounds the arms' growth within a step.
    double bound_at(const Eigen::Vector3d& centre, double R, const Snapshot& s, const double* dq) const {
        double a = 0, turn = 0;
        for (const int j : linear_joints) a += std::abs(dq[j]);
        for (std::size_t r = 0; r < rotaries.size(); ++r) {
            const double th = std::abs(dq[rotaries[r].joint]) * kPi / 180.0;
            if (th == 0) continue;
            const Eigen::Vector3d v = centre - s.line_point[r];
            const double arm = (v - v.dot(s.line_dir[r]) * s.line_dir[r]).norm() + R;
            a += th * arm;
            turn += th;
        }
        // The arms grow by at most what every point and axis moves within the step (each at
        // most the bound itself): D <= a + 2 turn D.
        return a / (1 - 2 * turn);
    }

    // The most any point of solid i moves in the part frame per unit of the sub-step from a to b
    // (`bow`: curve() over it): a Lipschitz bound, tight where bound() is loose. A point's
    // path p(u) has |p'(u) - (p(1) - p(0))| <= M / 2 with M >= |p''|; p(1) - p(0) is at most
    // the body frame's chord plus its turn times the body's radius; and with the joints moving
    // at constant rates, M <= 4 T^2 r + 3 T L (T: the rotaries' turn, L: the linear joints'
    // travel, r: the farthest a point or axis gets from a rotary axis). Derivation:
    // docs/machines.md, "Bodies".
    double rate(int i, const Snapshot& a, const Snapshot& b, double bow) const {
        if (!solids[std::size_t(i)].moves) return 0;
        const Body& body = *solids[std::size_t(i)].body;
        const Iso& pa = a.pose[std::size_t(i)];
        const Iso& pb = b.pose[std::size_t(i)];
        // The bounding sphere's centre: the body's chain frame origin.
        const Eigen::Vector3d& o = solids[std::size_t(i)].origin;
        const Eigen::Vector3d oa = pa * o, ob = pb * o;
        // A point at R from the origin moves by at most |Rb - Ra| R = 2 sin(turn / 2) R =
        // sqrt(3 - trace(Ra^T Rb)) R: no angle needed.
        const double tr = pa.linear().cwiseProduct(pb.linear()).sum();
        const double chord = (ob - oa).norm() + std::sqrt(std::max(0.0, 3 - tr)) * body.radius;
        return chord + bow;
    }
    Turns turns_of(const double* dq) const {
        Turns tt;
        for (const int j : linear_joints) tt.L += std::abs(dq[j]);
        for (std::size_t k = 0; k < rotaries.size() && k < tt.th.size(); ++k) {
            tt.th[k] = std::abs(dq[rotaries[k].joint]) * kPi / 180.0;
            tt.T += tt.th[k];
        }
        return tt;
    }
    // Half the bound on |p''| of rate() for a sphere of radius R about `centre` (base frame).
    double curve(const Eigen::Vector3d& centre, double R, const Snapshot& a, const Turns& tt) const {
        if (tt.T == 0) return 0;
        double r = 0, A = 0;
        for (std::size_t k = 0; k < rotaries.size(); ++k) {
            const double th = tt.th[k];
            if (th == 0) continue;
            // Every point of the body lies within its radius of the shape's centre.
            const Eigen::Vector3d v = centre - a.line_point[k];
            const double arm = (v - v.dot(a.line_dir[k]) * a.line_dir[k]).norm() + R;
            r = std::max(r, arm);
            A += th * arm;
        }
        r += 2 * (tt.L + A) / (1 - 2 * tt.T);  // how far points and axes get within the step (bound_at)
        return 0.5 * (4 * tt.T * tt.T * r + 3 * tt.T * tt.L);
    }
    // What the tests of one step (sa..sb of the piece) share: the tool axis' and the tip's
    // motion over it (part frame), for below().
    struct StepBound {
        Eigen::Vector3d n, tip;  // the tool axis and the tip at the step's start
        double Tn = 0;           // how far the tool axis turns over the step, at most (rad)
        double Dtip = 0;         // the tip's path length, at most
        double along = 0;        // the tip's motion along n, at most: |n . (tip1 - tip0)| + its bow
    };
    StepBound step_bound(const Snapshot& a, const Snapshot& b, const Turns& tt) const {
        StepBound sb;
        sb.n = a.tip.linear() * machine.tool_axis;
        sb.tip = a.tip.translation();
        // The tool axis turns at |n'| <= sum_k theta_k |w_k x n|; the angle between w_k and n
        // changes only by the other rotaries' turns (docs/machines.md, "Bodies").
        for (std::size_t k = 0; k < rotaries.size(); ++k) {
            const double th = tt.th[k];
            if (th == 0) continue;
            sb.Tn += th * std::min(1.0, a.line_dir[k].cross(a.axis_base).norm() + (tt.T - th));
        }
        const Eigen::Vector3d chord = b.tip.translation() - a.tip.translation();
        const double c = curve(a.tip_base, 0, a, tt);  // M / 2 for the tip
        sb.Dtip = chord.norm() + c;
        sb.along = std::abs(sb.n.dot(chord)) + 0.25 * c;
        return sb;
    }

    // Whether the box (centre c, half axes h, half diagonal `reach`; part frame, fixed there)
    // lies wholly below tool body t's lowest point along the tool axis over the whole step:
    // then they cannot meet. A point x's height over the tip, z = n . (x - tip), rises over
    // the step by at most Tn (|x - tip| + 2 Dtip) + along (docs/machines.md, "Bodies").
    bool below(int t, const Eigen::Vector3d& c, const Eigen::Vector3d* h, double reach, const StepBound& sb) const {
        return under(t, rise(c, h, reach, sb));
    }
    // The highest the box reaches along the tool axis over the tip, over the step: what below()
    // compares with each body's lowest point (the same for every tool body: computed once).
    [[gnu::always_inline]] static double rise(const Eigen::Vector3d& c, const Eigen::Vector3d* h, double reach, const StepBound& sb) {
        const Eigen::Vector3d d = c - sb.tip;
        const double top = sb.n.dot(d) + std::abs(sb.n.dot(h[0])) + std::abs(sb.n.dot(h[1])) + std::abs(sb.n.dot(h[2]));
        return top + sb.Tn * (d.norm() + reach + 2 * sb.Dtip) + sb.along;
    }
    bool under(int t, double rise) const {
        const double low = solids[std::size_t(t)].body->low;
        return low > -1e299 && rise < low - kContact;
    }

    static void grow(fcl::AABBd& box, double by) {
        box.min_ -= Eigen::Vector3d::Constant(by);
        box.max_ += Eigen::Vector3d::Constant(by);
    }

    // Whether tool body t, over the whole step from `step_a` (each of its points moving at most
    // step_rate, set by test_step), stays apart from the box `other`: its own box (in its
    // frame) grown by that much holds it all along; FCL's separating-axis test of two boxes.
    const Snapshot *step_a = nullptr, *step_b = nullptr;
    bool step_turns = true;  // whether a rotary turns over the step (test_step)
    double step_rate(int i) {
        double& d = D[std::size_t(i)];
        if (d >= 0) return d;
        if (step_turns) d = rate(i, *step_a, *step_b, bow[std::size_t(i)]);
        // No rotary turns: every frame keeps its rotation (bit for bit: snap()), so a body moves
        // by its translation's change alone.
        else d = solids[std::size_t(i)].moves ? (step_b->pose[std::size_t(i)].translation() - step_a->pose[std::size_t(i)].translation()).norm() : 0.0;
        return d;
    }
    // Tool body t's own box grown by step_rate(t) + kContact, in the part frame at the step's
    // start: made once a step (`held_ok`, cleared by test_step), for apart().
    struct Held {
        Eigen::Matrix3d axes;  // the body's axes, columns
        Eigen::Vector3d centre, extent;
    };
    std::vector<Held> held;
    std::vector<char> held_ok;
    const Held& held_box(int t) {
        Held& h = held[std::size_t(t)];
        if (held_ok[std::size_t(t)]) return h;
        const fcl::CollisionGeometryd& g = *solids[std::size_t(t)].object->collisionGeometry();
        const Iso& pose = step_a->pose[std::size_t(t)];
        h.axes = pose.linear();
        h.centre = pose * (0.5 * (g.aabb_local.min_ + g.aabb_local.max_));
        h.extent = 0.5 * (g.aabb_local.max_ - g.aabb_local.min_) + Eigen::Vector3d::Constant(step_rate(t) + kContact);
        held_ok[std::size_t(t)] = 1;
        return h;
    }
    bool apart(int t, const fcl::OBBd& other) {
        const Held& h = held_box(t);
        const Eigen::Vector3d w = other.To - h.centre;
        // The separating-axis test on the two boxes' own six face normals (of the fifteen: fewer
        // axes find fewer gaps, never a false one), the body's first, each row of R (the body's
        // axes against the other's) made only when its axis is tried: most gaps show on one.
        Eigen::Matrix3d R;
        for (int i = 0; i < 3; ++i) {
            const Eigen::Vector3d a = h.axes.col(i);
            R.row(i) = a.transpose() * other.axis;
            if (std::abs(a.dot(w)) > h.extent[i] + R.row(i).cwiseAbs().dot(other.extent)) return true;
        }
        for (int j = 0; j < 3; ++j)
            if (std::abs(other.axis.col(j).dot(w)) > other.extent[j] + R.col(j).cwiseAbs().dot(h.extent)) return true;
        return false;
    }
    std::vector<double> bow, D;  // per solid, this step: curve() and step_rate()
};

}  // namespace xlate5::collision_parts
