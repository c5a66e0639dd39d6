// SPDX-License-Identifier: GPL-3.0-or-later
// The split to tolerance. What it may call: see segment.hpp.
#include "translators/pipeline/segment.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>

#include "translators/constants.hpp"
#include "translators/error.hpp"
#include "translators/number.hpp"
#include "translators/pipeline/emitter.hpp"

namespace xlate5 {

namespace {

constexpr int kCheckSamples = Segmenter::kCheckSamples;
// The error between two of those samples can exceed both by a little (the tests measure it
// against 400-point sampling: under 1%); a piece passes only with this much room left.
constexpr double kSampleMargin = 0.97;
// A piece's length predicted from a failing try's error aims this far short of the limit.
constexpr double kPredictAim = 0.98;

// The joints as the firmware will be given them (each rounded to its printed decimals): the
// split and the report measure the path the firmware will really take.
void round_printed(const Machine& m, std::vector<double>& q) {
    for (std::size_t j = 0; j < q.size(); ++j) q[j] = printed_value(m, j, q[j]);
}
// The same of `from`, written to `to` (no copy first).
void round_printed(const Machine& m, const std::vector<double>& from, std::vector<double>& to) {
    to.resize(from.size());
    for (std::size_t j = 0; j < from.size(); ++j) to[j] = printed_value(m, j, from[j]);
}

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

PrintedRounding::PrintedRounding(const Kinematics& kinematics)
    : machine_(kinematics.machine()), joints_(kinematics.machine().joints.size()) {
    static constexpr double kPow10[] = {1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9};
    for (std::size_t j = 0; j < machine_.joints.size() && j < kMaxJoints; ++j) {
        const int d = printed_decimals(machine_, j);
        if (d < 0 || d > 9) {
            scale_[j] = 1;
            below_[j] = -1;  // never: printed_value for every value
            continue;
        }
        scale_[j] = kPow10[d];
        // |v * 10^d| below half of the smaller of to_units' limits (1e15 scaled, kMaxWritten
        // unscaled): both its range tests pass (a NaN fails this one too).
        below_[j] = 0.5 * std::min(1e15, kMaxWritten * kPow10[d]);
    }
    for (const int j : kinematics.rotary_joints())
        if (std::size_t(j) < kMaxJoints) rotaries_[rotary_count_++] = std::size_t(j);
}

bool PrintedRounding::round_end(const double* q1, double* to, double* exact, const double* from) const {
    const std::size_t n = joints_;
    bool rotates = false;
    for (std::size_t j = 0; j < n; ++j) {
        const double v = q1[j];
        exact[j] = v;
        const double scaled = v * scale_[j];
        // printed_value: to_units' units over the same power of ten.
        const double p = std::abs(scaled) < below_[j] ? double(round_half_away(scaled)) / scale_[j] : printed_value(machine_, j, v);
        to[j] = p;
    }
    for (std::size_t k = 0; k < rotary_count_; ++k) rotates |= to[rotaries_[k]] != from[rotaries_[k]];
    return rotates;
}

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

Segmenter::Segmenter(const Kinematics& kinematics)
    : ends_(kinematics),
      solutions_(kinematics),
      sample_angle_(kSampleMargin * kinematics.machine().motion.angle_tolerance),
      chord_limit_(chord_within(sample_angle_.degrees() - 1e-6)),
      kin_(kinematics),
      machine_(kinematics.machine()),
      joints_(kinematics.machine().joints.size()),
      limits_(kinematics.machine()),
      rounding_(kinematics) {}

const GreatArc& Segmenter::arc_of(const MoveSpec& mv) const {
    if (!(mv.p0.axis == arc_.a && mv.p1.axis == arc_.b)) arc_ = GreatArc(mv.p0.axis, mv.p1.axis);
    return arc_;
}

Pose Segmenter::pose_at(const MoveSpec& mv, double s) const {
    Pose p;
    p.tip = mv.p0.tip + s * (mv.p1.tip - mv.p0.tip);
    p.axis = arc_of(mv).at(s);
    return p;
}

IkResult Segmenter::solve_at(const MoveSpec& mv, double s, const std::vector<double>& previous, std::vector<double>& q,
                               int branch) const {
    if (mv.mode == OrientationMode::Angles) {
        const auto& q0 = *mv.q0;
        const auto& q1 = *mv.q1;
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

void Segmenter::target_at(const MoveSpec& mv, double s, Target& target) const {
    target.pose = pose_at(mv, s);
    target.solutions = kin_.orientation_solutions(target.pose.axis);
}

IkResult Segmenter::orient_at(const MoveSpec& mv, double s, const Target& target, const std::vector<double>& previous,
                                std::vector<double>& q, int branch, ChosenSolution& chosen) const {
    const auto& q0 = *mv.q0;
    const auto& q1 = *mv.q1;
    q = previous;
    // A free joint (axis along the tool) follows the line from its start to its end value.
    std::vector<double>& hint = const_cast<std::vector<double>&>(lerp_);
    hint.resize(q.size());
    for (std::size_t j = 0; j < q.size(); ++j) hint[j] = q0[j] + s * (q1[j] - q0[j]);
    return branch < 0 ? orient_within_limits(machine_, kin_.rotary_joints(), target.solutions, previous, hint, q, &chosen)
                      : orient_on_branch(machine_, kin_.rotary_joints(), target.solutions, branch, previous, hint, q, &chosen);
}

IkResult Segmenter::place(const Target& target, std::vector<double>& q, ChosenSolution chosen) const {
    if (auto rp = kin_.solve_position(target.pose.tip, q, nullptr, nullptr, chosen); !rp.ok()) return rp;
    return limits_.contains(q) ? IkResult{} : check_limits(machine_, q);
}

bool Segmenter::same_rotaries(const std::vector<double>& a, const std::vector<double>& b) const {
    for (const int j : kin_.rotary_joints())
        if (std::memcmp(&a[std::size_t(j)], &b[std::size_t(j)], sizeof(double)) != 0) return false;
    return true;
}

IkResult Segmenter::leaves_limits(const MoveSpec& mv, double s, const std::vector<double>& previous) const {
    if (mv.mode != OrientationMode::Vector) return {};
    std::vector<double>& cont = sample_;
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

void Segmenter::piece_error(const MoveSpec& mv, double sa, double sb, const double* qa, const double* qb, int samples,
                              double& tip, double& angle) const {
    tip = 0;
    angle = 0;
    std::vector<double>& q = sample_;
    q.resize(joints_);
    const GreatArc arc = arc_of(mv);  // a copy: a nested split may cache another move's
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

bool Segmenter::piece_within(const MoveSpec& mv, double sa, double sb, const double* qa, const double* qb, double tol,
                               double* middle_ratio) const {
    const double atol = sample_angle_.degrees();
    // The same points as piece_error's, the middle first (where a chord's error is largest): a
    // piece that fails usually fails there, and the other six are not computed. A piece passes
    // exactly when piece_error's largest values would pass.
    static constexpr int kOrder[kCheckSamples] = {4, 2, 6, 1, 3, 5, 7};
    std::vector<double>& q = sample_;
    q.resize(joints_);
    const GreatArc arc = arc_of(mv);  // a copy: a nested split may cache another move's
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
    // The move's printed end (split passes q1_printed_ itself), a rounding of the solve's own
    // end: bounded from it, no FK.
    if (solved && is_end && kin_.path_bound().near_end(*solved, q, c.end)) return c.end;
    c.end = kin_.path_end(q);
    return c.end;
}

bool Segmenter::reach_clears(const MoveSpec& mv, double tol) const {
    // The whole move under the angle form, with no FK: kinematics' bound from the machine's
    // reach (it holds anywhere inside the limits), and the printed ends' distance from the line
    // at most how far rounding moves the tip from the exact ends, which are on it. A pass here
    // is a pass of the bound below and of the samples; a fail decides nothing (they run).
    const JointPathBound& bound = kin_.path_bound();
    if (mv.mode != OrientationMode::Angles || !bound.has_reach()) return false;
    constexpr double kSlack = 1e-9;  // as bounded_within's
    const Kinematics::PathBound b = bound.joint_path_bound(bound.reach(), q0_printed_.data(), q1_printed_.data());
    if (!(b.tip <= tol - kSlack)) return false;
    // The start's shift is the last move's end's, measured by the split before this one when it
    // got here (split calls this only for a move that starts at the last one's end, joints and
    // tip): the same values, the same sum.
    const double start = shift_split_ + 1 == splits_ ? end_shift_ : bound.reach_shift(mv.q0->data(), q0_printed_.data());
    const double end = bound.reach_shift(mv.q1->data(), q1_printed_.data());
    end_shift_ = end;
    shift_split_ = splits_;
    const double ends = std::max(start, end);
    return b.tip + ends <= tol - kSlack;
}

bool Segmenter::bounded_within(const MoveSpec& mv, double sa, double sb, const double* qa, const double* qb, double tol) const {
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
    const GreatArc arc = arc_of(mv);  // a copy: a nested split may cache another move's
    const Eigen::Vector3d ia = sa == 0.0 ? mv.p0.axis : arc.at(sa);
    const Eigen::Vector3d ib = sb == 1.0 ? mv.p1.axis : arc.at(sb);
    const double phi = (sb - sa) * arc.angle;
    return b.axis + std::max((pa.axis - ia).norm() + pa_axis_slack, (pb.axis - ib).norm() + eb.axis_slack) + phi * phi / 8.0 < chord_limit_;
}

IkResult Segmenter::split(const MoveSpec& mv) {
    ++splits_;
    // A move usually starts where the one before ended: its start as printed is known then.
    // And every move ends exactly on its programmed tip (the planner solves the linear joints
    // for it): a move that starts at the last one's end, joints and tip, starts on its line.
    const bool from_last = *mv.q0 == last_end_q_;
    const bool start_on_line = from_last && mv.p0.tip == last_end_tip_;
    // q1_printed_ holds the last move's end as printed (last_end_q_ rounded): taken, then refilled.
    // The ends' slots (path_end) follow: the last end's is the start's now.
    if (from_last) q0_printed_.swap(q1_printed_);
    else round_printed(machine_, *mv.q0, q0_printed_);
    ends_.next_move(from_last);
    const std::size_t n = joints_;
    bool rotates = false;
    if (n <= kMaxJoints && mv.q1->size() == n && q0_printed_.size() == n && q1_printed_.size() == n && last_end_q_.size() == n) {
        // The usual move (every one after the first): one pass, no copies or calls.
        rotates = rounding_.round_end(mv.q1->data(), q1_printed_.data(), last_end_q_.data(), q0_printed_.data());
    } else {
        round_printed(machine_, *mv.q1, q1_printed_);
        last_end_q_ = *mv.q1;
        for (const int j : kin_.rotary_joints()) rotates = rotates || q1_printed_[std::size_t(j)] != q0_printed_[std::size_t(j)];
    }
    solved_end_ = nullptr;
    last_end_tip_ = mv.p1.tip;
    final_moved_ = false;
    const auto& q0 = q0_printed_;
    const auto& q1 = q1_printed_;
    // One piece, the whole move: read from q1_printed_ and the move's own end (no copies).
    if (s_.size() == 1) s_[0] = 1.0;
    else s_.assign(1, 1.0);
    whole_ = true;
    // With the rotaries still the tip is affine in the linear joints: the firmware's line is exact.
    if (!rotates || mv.mode == OrientationMode::Joints || !machine_.motion.segment) return {};
    if (mv.end && mv.end->valid && mv.end->q == *mv.q1) solved_end_ = mv.end;

    const double tol = kSampleMargin * machine_.motion.tolerance;
    if (start_on_line && reach_clears(mv, tol)) return {};
    if (bounded_within(mv, 0, 1, q0.data(), q1.data(), tol)) return {};
    return march(mv, tol);
}

// Near a pole the continuous branch swings a joint round; the other branch may cut across within
// the tolerance (a tilt through zero instead of a half turn): true, with qb and exact_b_ that
// branch's end, when one passes.
bool Segmenter::other_branch_passes(const MoveSpec& mv, double sa, double sb, const std::vector<double>& qa,
                                    std::vector<double>& qb, double tol) {
    std::vector<double>& alt = scratch_b_;
    for (int b = 0; b < 2; ++b) {
        // solve_at(mv, sb, qa, alt, b), on the try's own target. A branch whose rotaries are the
        // continuous solve's to the bit is the branch it took: the position solve would give
        // exact_b_ again, qb once rounded, which the test below skips; it is skipped here, before
        // that solve.
        ChosenSolution chosen;
        if (!orient_at(mv, sb, target_, qa, alt, b, chosen).ok()) continue;
        if (same_rotaries(alt, exact_b_)) continue;
        if (!place(target_, alt, chosen).ok()) continue;
        std::vector<double>& alt_exact = alt_exact_;  // a member: no allocation per try
        alt_exact = alt;
        round_printed(machine_, alt);
        if (alt == qb) continue;
        if (bounded_within(mv, sa, sb, qa.data(), alt.data(), tol) || piece_within(mv, sa, sb, qa.data(), alt.data(), tol)) {
            qb = alt;
            exact_b_ = alt_exact;
            return true;
        }
    }
    return false;
}

// A polar machine (Kinematics::is_polar) takes C from the tip where the tool axis is along C: of
// the two angles that put the tip in its plane (half a turn apart, X of either sign), the one
// nearest the free joint's hint, which follows the line from the move's start value to its end
// value. Where the programmed line passes near C's axis the tip's angle swings round faster than
// that line, and the nearest angle to the hint jumps half a turn: no piece across the jump stays
// within the tolerance, however short. Then C is taken nearest the piece's start instead (the
// swing the tip really makes): true, with qb and exact_b_ that end, when its piece passes.
bool Segmenter::polar_continuous_passes(const MoveSpec& mv, double sa, double sb, const std::vector<double>& qa,
                                        std::vector<double>& qb, double tol) {
    bool jumped = false;
    for (const int j : kin_.rotary_joints()) jumped = jumped || std::abs(exact_b_[std::size_t(j)] - qa[std::size_t(j)]) > 60.0;
    if (!jumped) return false;
    std::vector<double>& alt = scratch_b_;
    alt = qa;
    ChosenSolution chosen;
    if (!orient_within_limits(machine_, kin_.rotary_joints(), target_.solutions, qa, qa, alt, &chosen).ok()) return false;
    if (!place(target_, alt, chosen).ok()) return false;
    std::vector<double>& alt_exact = alt_exact_;
    alt_exact = alt;
    round_printed(machine_, alt);
    if (!bounded_within(mv, sa, sb, qa.data(), alt.data(), tol) && !piece_within(mv, sa, sb, qa.data(), alt.data(), tol)) return false;
    qb = alt;
    exact_b_ = alt_exact;
    return true;
}

// The longest piece from sa (joints qa = march_a_, as printed) that passes: halved until one
// passes, then closed in on the limit between the longest passing and the shortest failing
// length. Its length in ok_len, its end in scratch_a_ (as printed) and ok_exact_ (as solved).
IkResult Segmenter::longest_piece(const MoveSpec& mv, double tol, double sa, double step, double& ok_len) {
    const auto& q1 = q1_printed_;
    const std::vector<double>& qa = march_a_;
    std::vector<double>& qb = march_b_;
    double bad_len = 0;
    ok_len = 0;
    std::vector<double>& qok = scratch_a_;
    double len = std::min(1.0 - sa, step);
    bool predicted = false;  // this try's length came from the error measured on a failing one
    int predictions = 0;
    for (int refine = 0;;) {
        const double sb = sa + len;
        IkResult r;
        if (sb >= 1.0 && mv.mode == OrientationMode::Angles) {
            qb = q1;  // angle form fixes the end
        } else if (mv.mode == OrientationMode::Vector) {
            // solve_at's steps, the target kept for the other branches' tries below.
            target_at(mv, std::min(sb, 1.0), target_);
            ChosenSolution chosen;
            r = orient_at(mv, std::min(sb, 1.0), target_, qa, qb, -1, chosen);
            if (r.ok()) r = place(target_, qb, chosen);
        } else {
            r = solve_at(mv, std::min(sb, 1.0), qa, qb);
        }
        if (!r.ok()) {
            r.message += " (at " + std::to_string(int(std::lround(std::min(sb, 1.0) * 100))) + "% of the move)";
            return r;
        }
        if (sb >= 1.0 && mv.mode == OrientationMode::Angles) exact_b_ = *mv.q1;
        else exact_b_ = qb;
        round_printed(machine_, qb);
        double middle_ratio = 0;  // the failing middle sample's error over the tolerance (0: not known)
        bool pass = bounded_within(mv, sa, std::min(sb, 1.0), qa.data(), qb.data(), tol);
        if (!pass) pass = piece_within(mv, sa, std::min(sb, 1.0), qa.data(), qb.data(), tol, &middle_ratio);
        if (!pass && mv.mode == OrientationMode::Vector) pass = other_branch_passes(mv, sa, std::min(sb, 1.0), qa, qb, tol);
        if (!pass && mv.mode == OrientationMode::Vector && kin_.is_polar()) pass = polar_continuous_passes(mv, sa, std::min(sb, 1.0), qa, qb, tol);
        if (pass) {
            ok_len = len;
            qok = qb;
            ok_exact_ = exact_b_;
        } else {
            bad_len = len;
            if (len < 1e-9) {
                // Either a pole, or the continuous solution runs out of a joint's limits here
                // and the nearest one inside them is on another branch or turn: say which.
                if (auto rl = leaves_limits(mv, std::min(sb, 1.0), qa); !rl.ok()) return rl;
                return {IkStatus::Singular, "the tool axis passes a pole here: a rotary joint would have to turn instantly"};
            }
        }
        if (ok_len > 0 && (bad_len == 0 || (pass && predicted) || ++refine >= 4 || bad_len - ok_len < 0.02 * ok_len)) break;
        // A chord's error grows with the square of the piece's length: a try that failed at
        // its middle point (where that error is largest) by the ratio r gives the length that
        // just passes, len / sqrt(r); aimed a little short of it (the ends' rounding adds an
        // error that does not shrink with the piece), that try usually passes and is taken.
        // Twice wrong (a path that does not follow the rule), the search halves as before.
        predicted = !pass && middle_ratio > 1 && predictions < 2;
        if (predicted) {
            ++predictions;
            len = len / std::sqrt(middle_ratio) * kPredictAim;
            if (len >= kPredictAim * (1.0 - sa)) len = 1.0 - sa;  // the rest of the move looks within reach: no sliver left at the end
            if (len <= ok_len) break;  // the longest passing try is already as long
        } else {
            len = ok_len > 0 ? 0.5 * (ok_len + bad_len) : 0.5 * len;
        }
    }
    return {};
}

IkResult Segmenter::march(const MoveSpec& mv, double tol) {
    const auto& q0 = q0_printed_;
    const auto& q1 = q1_printed_;
    const double atol = sample_angle_.degrees();
    double tip = 0, ang = 0;
    piece_error(mv, 0, 1, q0.data(), q1.data(), kCheckSamples, tip, ang);
    const double ratio = std::max(tip / tol, ang / atol);
    if (ratio <= 1) return {};

    // March along the move from s = 0, each piece as long as the tolerance allows (greedy
    // farthest reach, which gives the fewest pieces when the error grows with piece length), each
    // point solved from the one before so the solution stays on one continuous branch. The
    // chord error of a smooth path falls with the square of the piece length, which gives the
    // first guess of the step.
    s_.clear();
    qs_.clear();
    qs_exact_.clear();
    whole_ = false;
    double step = 1.0 / std::ceil(std::sqrt(ratio));
    double sa = 0;
    std::vector<double>& qa = march_a_;
    std::vector<double>& qb = march_b_;
    qa = q0;
    while (sa < 1.0) {
        double ok_len = 0;
        if (auto r = longest_piece(mv, tol, sa, step, ok_len); !r.ok()) return r;
        const std::vector<double>& qok = scratch_a_;
        const double sb = std::min(1.0, sa + ok_len);
        qb = qok;
        if (sb >= 1.0) {
            final_exact_ = ok_exact_;
            final_moved_ = true;
        }
        step = std::max(sb - sa, 1e-9) * 1.25;  // the next piece is likely about as long: start a bit farther
        s_.push_back(sb);
        qs_.insert(qs_.end(), qb.begin(), qb.end());
        qs_exact_.insert(qs_exact_.end(), ok_exact_.begin(), ok_exact_.end());
        const int bound = pieces_bound(machine_.motion.max_pieces);
        if (int(s_.size()) > bound)  // refused, not silently truncated (docs/limits.md)
            return {IkStatus::Singular, "the move needs more than " + std::to_string(bound) +
                                            " pieces to stay within the tolerance (the bound on pieces per input line)"};
        sa = sb;
        qa.swap(qb);
    }
    return {};
}

double Segmenter::split_rotary_travel() const {
    // Degrees the rotaries turn along the pieces split() made last, from the printed start.
    const auto& rot = kin_.rotary_joints();
    double travel = 0;
    const double* qa = q0_printed_.data();
    for (std::size_t k = 0; k < s_.size(); ++k) {
        const double* qb = piece_printed(k);
        for (const int j : rot) travel += std::abs(qb[std::size_t(j)] - qa[std::size_t(j)]);
        qa = qb;
    }
    return travel;
}

}  // namespace xlate5
