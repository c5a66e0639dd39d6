// SPDX-License-Identifier: GPL-3.0-or-later
// The split's test of one piece. What it may call: see split_check.hpp.
#include "translators/pipeline/split_check.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

#include "translators/constants.hpp"

namespace xlate5 {

namespace {

// Distance from p to the segment ab.
double segment_distance(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
    const Eigen::Vector3d ab = b - a;
    const double len2 = ab.squaredNorm();
    double t = len2 > 0 ? (p - a).dot(ab) / len2 : 0.0;
    t = std::clamp(t, 0.0, 1.0);
    return (a + t * ab - p).norm();
}

// Distance from an end to the segment: zero, with no arithmetic, when the end is the segment's
// own end point (a bounded end's pose is the programmed tip itself).
double end_distance(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
    return p == a || p == b ? 0.0 : segment_distance(p, a, b);
}

}  // namespace

PieceCheck::PieceCheck(const Kinematics& kinematics, const SplitPoints& points, double angle_degrees)
    : kin_(kinematics),
      points_(points),
      joints_(kinematics.machine().joints.size()),
      sample_angle_(angle_degrees),
      chord_limit_(chord_within(sample_angle_.degrees() - 1e-6)),
      ends_(kinematics) {}

void PieceCheck::piece_error(const PlannedMove& mv, double sa, double sb, const double* qa, const double* qb, int samples,
                              double& tip, double& angle) const {
    tip = 0;
    angle = 0;
    std::vector<double>& q = sample_;
    q.resize(joints_);
    const GreatArc arc = points_.arc_of(mv);  // a copy: a nested split may cache another move's
    for (int i = 1; i <= samples; ++i) {
        const double t = double(i) / double(samples + 1);
        for (std::size_t j = 0; j < q.size(); ++j) q[j] = qa[j] + t * (qb[j] - qa[j]);
        const Pose fw = kin_.forward(q);
        tip = std::max(tip, segment_distance(fw.tip, mv.p0.tip, mv.p1.tip));
        if (mv.mode == OrientationMode::Vector) {
            const Eigen::Vector3d ideal = arc.at(sa + t * (sb - sa));
            angle = std::max(angle, std::acos(std::clamp(fw.axis.dot(ideal), -1.0, 1.0)) * kDegPerRad);
        }
    }
}

bool PieceCheck::piece_within(const PlannedMove& mv, double sa, double sb, const double* qa, const double* qb, double tol,
                               double* middle_ratio) const {
    const double atol = sample_angle_.degrees();
    // The same points as piece_error's, the middle first (where a chord's error is largest): a
    // piece that fails usually fails there, and the other six are not computed. A piece passes
    // exactly when piece_error's largest values would pass.
    static constexpr int kOrder[kCheckSamples] = {4, 2, 6, 1, 3, 5, 7};
    std::vector<double>& q = sample_;
    q.resize(joints_);
    const GreatArc arc = points_.arc_of(mv);  // a copy: a nested split may cache another move's
    // Once the middle point has passed, the other points are checked against kinematics' bound
    // first, and computed only where it does not clear them. At parameter t the path lies within
    // 4 t (1 - t) of the middle's bound of the chord between its ends (kinematics.cpp: a t (1 - t)
    // / 2 with a / 8 at the middle), a point of that chord within the farther end's distance of
    // the programmed segment (distance to a segment is convex), and for the tool axis the
    // great-circle arc within 4 t (1 - t) phi^2 / 8 of its own chord. A point so cleared is
    // within the tolerance, so it would have passed: the verdict is the same.
    constexpr double kSlack = 1e-9;  // as bounded_within's
    bool bounded = false;
    double curve = 0, ends = 0, axis_curve = 0, axis_ends = 0, arc_curve = 0;
    for (const int i : kOrder) {
        const double t = double(i) / double(kCheckSamples + 1);
        if (bounded) {
            const double f = 4 * t * (1 - t);
            bool clear = curve * f + ends <= tol - kSlack;
            if (clear && mv.mode == OrientationMode::Vector) {
                clear = (axis_curve + arc_curve) * f + axis_ends < chord_limit_;
            }
            if (clear) continue;
        }
        for (std::size_t j = 0; j < q.size(); ++j) q[j] = qa[j] + t * (qb[j] - qa[j]);
        const Pose fw = kin_.forward(q);
        const bool middle = i == kOrder[0];
        if (const double d = segment_distance(fw.tip, mv.p0.tip, mv.p1.tip); d > tol) {
            if (middle && middle_ratio) *middle_ratio = d / tol;
            return false;
        }
        if (mv.mode == OrientationMode::Vector) {
            const Eigen::Vector3d ideal = arc.at(sa + t * (sb - sa));
            // The limit tested on the dot product (the acos only near it).
            const double dot = fw.axis.dot(ideal);
            if (sample_angle_.above(dot)) {
                if (middle && middle_ratio) *middle_ratio = angle_of_dot(dot) / atol;
                return false;
            }
        }
        if (middle) {
            // The ends' FK: qb's is kept for the next piece, which starts there when this one passes.
            const Kinematics::PathEnd& ea = path_end(qa);
            const Kinematics::PathBound b = kin_.path_bound().joint_path_bound(ea, qa, qb);
            if (!std::isfinite(b.tip)) continue;
            // Copies of the start's pose and slacks (the next call may reuse the slot); a bounded
            // end (near_end) is within its slacks of its pose.
            const Pose pa = ea.pose;
            const double pa_tip_slack = ea.tip_slack, pa_axis_slack = ea.axis_slack;
            const Kinematics::PathEnd& eb = path_end(qb);
            const Pose& pb = eb.pose;
            curve = b.tip;
            ends = std::max(end_distance(pa.tip, mv.p0.tip, mv.p1.tip) + pa_tip_slack, end_distance(pb.tip, mv.p0.tip, mv.p1.tip) + eb.tip_slack);
            if (mv.mode == OrientationMode::Vector) {
                const Eigen::Vector3d ia = sa == 0.0 ? mv.p0.axis : arc.at(sa);
                const Eigen::Vector3d ib = sb == 1.0 ? mv.p1.axis : arc.at(sb);
                const double phi = (sb - sa) * arc.angle;
                axis_curve = b.axis;
                axis_ends = std::max((pa.axis - ia).norm() + pa_axis_slack, (pb.axis - ib).norm() + eb.axis_slack);
                arc_curve = phi * phi / 8.0;
            }
            bounded = true;
        }
    }
    return true;
}

bool PieceCheck::reach_clears(const PlannedMove& mv, double tol) const {
    // The whole move under the angle form, with no FK: kinematics' bound from the machine's
    // reach (it holds anywhere inside the limits), and the printed ends' distance from the line
    // at most how far rounding moves the tip from the exact ends, which are on it. A pass here
    // is a pass of the bound below and of the samples; a fail decides nothing (they run).
    const JointPathBound& bound = kin_.path_bound();
    if (mv.mode != OrientationMode::Angles || !bound.has_reach()) return false;
    constexpr double kSlack = 1e-9;  // as bounded_within's
    const Kinematics::PathBound b = bound.joint_path_bound(bound.reach(), start_, end_);
    if (!(b.tip <= tol - kSlack)) return false;
    // The start's shift is the last move's end's, measured by the split before this one when it
    // got here (split calls this only for a move that starts at the last one's end, joints and
    // tip): the same values, the same sum.
    const double start = shift_split_ + 1 == splits_ ? end_shift_ : bound.reach_shift(mv.q0.data(), start_);
    const double end = bound.reach_shift(mv.q1.data(), end_);
    end_shift_ = end;
    shift_split_ = splits_;
    const double ends = std::max(start, end);
    return b.tip + ends <= tol - kSlack;
}

bool PieceCheck::bounded_within(const PlannedMove& mv, double sa, double sb, const double* qa, const double* qb, double tol) const {
    // Sampling finds at most the true deviation, and the bound is at least that: when the bound
    // passes, the samples would have too, so the split is the same, only cheaper. The slack
    // covers rounding in the two computations.
    constexpr double kSlack = 1e-9;
    const Kinematics::PathEnd& ea = path_end(qa);
    const Kinematics::PathBound b = kin_.path_bound().joint_path_bound(ea, qa, qb);
    // The path lies within b.tip of the chord between its ends, and that chord within the
    // farther end's distance of the programmed segment. The first part alone often decides (a
    // piece being lengthened to the tolerance): then no FK at qb.
    if (!(b.tip <= tol - kSlack)) return false;
    // Copies of the start's pose and slacks: the next call may reuse the slot. An end bounded
    // rather than measured (near_end) is within its slacks of its pose.
    const Pose pa = ea.pose;
    const double pa_tip_slack = ea.tip_slack, pa_axis_slack = ea.axis_slack;
    const Kinematics::PathEnd& eb = path_end(qb);
    const Pose& pb = eb.pose;
    const double ends = std::max(end_distance(pa.tip, mv.p0.tip, mv.p1.tip) + pa_tip_slack, end_distance(pb.tip, mv.p0.tip, mv.p1.tip) + eb.tip_slack);
    if (!(b.tip + ends <= tol - kSlack)) return false;
    if (mv.mode != OrientationMode::Vector) return true;
    // The tool axis against the great-circle arc from sa to sb: both lie near the chords between
    // their ends (the arc within phi^2 / 8 of its own), and those chords within the ends' gaps.
    if (sa == 0.0 && sb == 1.0) {
        // The whole move (most moves pass here): the arc's angle alone, bounded from the axes'
        // dot product (no acos, no sine).
        const double phi2 = turn_squared_at_most(mv.p0.axis.dot(mv.p1.axis));
        return b.axis + std::max((pa.axis - mv.p0.axis).norm() + pa_axis_slack, (pb.axis - mv.p1.axis).norm() + eb.axis_slack) + phi2 / 8.0 <
               chord_limit_;
    }
    const GreatArc arc = points_.arc_of(mv);  // a copy: a nested split may cache another move's
    const Eigen::Vector3d ia = sa == 0.0 ? mv.p0.axis : arc.at(sa);
    const Eigen::Vector3d ib = sb == 1.0 ? mv.p1.axis : arc.at(sb);
    const double phi = (sb - sa) * arc.angle;
    return b.axis + std::max((pa.axis - ia).norm() + pa_axis_slack, (pb.axis - ib).norm() + eb.axis_slack) + phi * phi / 8.0 < chord_limit_;
}

const Kinematics::PathEnd& EndCache::find(const double* q, bool is_end, const Kinematics::SolvedEnd* solved) const {
    const std::size_t n = joints_;
    for (int i = 0; i < 2; ++i) {
        Slot& c = slots_[i];
        if (c.n == n && std::equal(q, q + n, c.q)) {
            if (is_end) end_slot_ = i;
            return c.end;
        }
    }
    const int k = next_;
    Slot& c = slots_[k];
    next_ = 1 - next_;
    if (start_slot_ == k) start_slot_ = -1;
    if (end_slot_ == k) end_slot_ = -1;
    c.n = 0;  // (no machine has more joints than a slot holds: kinematics takes at most kMaxJoints)
    if (n <= kMaxJoints) {
        c.n = n;
        std::copy(q, q + n, c.q);
        // The slot found again for the next move's start (not for a NaN joint, which the
        // search never finds).
        if (is_end && std::all_of(q, q + n, [](double v) { return v == v; })) end_slot_ = k;
    }
    // The move's printed end (set_ends: the pieces' printed end itself), a rounding of the solve's own
    // end: bounded from it, no FK.
    if (solved && is_end && kin_.path_bound().near_end(*solved, q, c.end)) return c.end;
    c.end = kin_.path_end(q);
    return c.end;
}

}  // namespace xlate5
