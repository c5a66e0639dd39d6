// SPDX-License-Identifier: GPL-3.0-or-later
// The pole policy. What it may call: see pole_policy.hpp.
#include "translators/pipeline/pole_policy.hpp"

#include <algorithm>
#include <bit>
#include <cmath>

#include "translators/constants.hpp"
#include "translators/pipeline/joint_limits.hpp"

namespace xlate5 {

namespace {
double angle_between(const Eigen::Vector3d& a, const Eigen::Vector3d& b) { return angle_of_dot(a.dot(b)); }
}  // namespace

PoleHold::PoleHold(const Kinematics& kinematics)
    : kin_(kinematics),
      machine_(kinematics.machine()),
      region_(kPoleRegion * kinematics.machine().motion.angle_tolerance),
      short_turn_(kinematics.machine().motion.angle_tolerance),
      wide_turn_(kPoleWideTurns * kinematics.machine().motion.angle_tolerance),
      exact_start_(least_dot_below(1e-6)),
      chord_limit_(chord_within(kPoleMargin * kinematics.machine().motion.angle_tolerance - kPoleSlack)) {
    // The pole of a has_flip machine: the tool axis with the tilting rotary at 0, which the first
    // rotary then turns about itself (has_flip: within 1e-9 of its axis), so it is the same for
    // every joint value.
    const auto& rot = kin_.rotary_joints();
    if (rot.size() == 2 && kin_.has_flip()) {
        std::vector<double> q = machine_.home_joints();
        q[std::size_t(rot[1])] = 0;
        pole_ = kin_.tool_axis(q);
    }
    checks_ = rot.size() == 2 && kin_.has_flip() && machine_.motion.segment;
    polar_ = kin_.is_polar();
    if (checks_) c_ = std::size_t(rot[0]), b_ = std::size_t(rot[1]);
}

// The tool axis at q's rotaries: a remembered one when they are the same to the bit (a move's
// end is the next one's start), else tool_axis(q). passage's machines only (two rotaries).
// The older slot first: it holds the end of the move before, this move's start (the newer one
// holds this move's usual end). The remembered axes are the position solve's, computed from the
// rotaries alone (rotations; the linear joints only translate): tool_axis(q) to the bit, or to
// rounding where the solve took the rotaries' sines from the orientation solve (a two-turn
// table's closed form); either way the slots are tried in a fixed order, so the answer is the
// same on every run.
Eigen::Vector3d PoleHold::axis_at(const std::vector<double>& q) const {
    const std::uint64_t qc = std::bit_cast<std::uint64_t>(q[c_]), qb = std::bit_cast<std::uint64_t>(q[b_]);
    const KnownAxis& older = known_[known_next_];
    if (older.holds(qc, qb)) return older.axis;
    const KnownAxis& newer = known_[1 - known_next_];
    if (newer.holds(qc, qb)) return newer.axis;
    return kin_.tool_axis(q);
}

void PoleHold::remember_axis(const std::vector<double>& q, const Eigen::Vector3d& axis) {
    // Two slots: a move's end is remembered before the pole check asks for its start (the end
    // of the move before). Called only where passage applies (two rotaries).
    KnownAxis& k = known_[known_next_];
    known_next_ = 1 - known_next_;
    k.rotary[0] = std::bit_cast<std::uint64_t>(q[c_]);
    k.rotary[1] = std::bit_cast<std::uint64_t>(q[b_]);
    k.axis = axis;
    k.valid = true;
}

// The tests every move makes, cheapest first; most moves leave here (see hold). Small, so
// that Planner::plan takes it inline.
bool PoleHold::passage(const std::vector<double>& q0, const std::vector<double>& usual, const Pose& from, const Pose& to,
                       const Kinematics::Solutions* at_end, std::vector<double>& q, double& worst, bool need_worst,
                       bool& start_held, PoleChoices& choices) {
    // Machines whose tool axis at zero lies along the first rotary (has_flip): there the pole is
    // that rotary's axis and the second tilts the tool along a great circle through it.
    if (!checks_) return false;
    const std::size_t c = c_, b = b_;
    const bool start_exact = axis_at(q0).dot(from.axis) >= exact_start_;
    start_held = !start_exact;
    // From an exact start, a move whose usual end turns no rotary has nothing to hold (planar
    // files under G43.5: the axis stays on the pole).
    if (start_exact && usual[c] == q0[c] && usual[b] == q0[b]) return false;
    // The tilt from the pole (the nearer of its two ends) is below the region; its value is
    // needed only then. The dot with -pole is -d to the bit (each product and sum only changes
    // sign; a zero sum's sign aside, which neither comparison nor acos tells apart).
    const double d = to.axis.dot(pole_);
    const bool near_pole = region_.below(d) || region_.below(-d);
    // A polar machine (core-rtheta) takes C from the tip at the pole (Kinematics::is_polar): C is
    // not free there, and a held C would only have the position solve turn it back, half a turn
    // at a time.
    if (near_pole && polar_) return false;
    if (start_exact && !near_pole) return false;
    // Only a move turning the tool axis by less than the tolerance may end off its axis: a
    // passage made of such moves cannot cross in any one of them. A longer move ends exactly
    // where it was programmed (a crossing within it is the motion stage's).
    const double turned = from.axis.dot(to.axis);
    const bool short_move = short_turn_.below(turned) || (choices.wide && wide_turn_.below(turned));
    if (start_exact && !short_move) return false;
    return hold(q0, usual, from, to, at_end, q, worst, need_worst, start_exact, near_pole && short_move, choices);
}

// The rest of passage, out of line: a move near the pole, or from an inexact start.
// hold's end near the pole (see kPoleHold): the turntable held within its budget of an exact
// solution's angle, the tilt the nearest point of that great circle to the axis. False when that
// end is not to be taken (out of reach, past the budget, or the usual end from an exact start).
bool PoleHold::held_end(const std::vector<double>& q0, const std::vector<double>& usual, const Pose& to,
                        const Kinematics::Solutions* at_end, std::vector<double>& q, Eigen::Vector3d& end_axis,
                        bool start_exact, PoleChoices& choices, bool& flipped) const {
    const std::size_t c = c_, b = b_;
    const double tolerance = machine_.motion.angle_tolerance;
    const double region = kPoleRegion * tolerance, hold = kPoleHold * tolerance;
    const Eigen::Vector3d& pole = pole_;
    const double tilt = std::min(angle_between(to.axis, pole), angle_between(to.axis, -pole));
    const double budget = tilt <= hold ? hold : hold * (region - tilt) / (region - hold);
    // The turntable may stay this far off an exact solution's angle.
    const double st = std::sin(tilt / kDegPerRad), sb = std::sin(budget / kDegPerRad);
    const double off = st > sb ? std::asin(sb / st) * kDegPerRad : 180.0;
    const Kinematics::Solutions solutions = at_end ? *at_end : kin_.orientation_solutions(to.axis);
    // Each exact angle is taken on a turn inside the joint's limits (the nearest such): held
    // toward one past them, the turntable would have to leave the region on the far side of
    // its limit (rw2's A at its -168 home, the axis leaning toward +-180), so it is steered
    // toward the one it can reach while the axis is still near the pole and any angle will do.
    const Joint& J = machine_.joints[c];
    double options[2];  // a solution set holds at most two
    int n = 0;
    for (int k = 0; k < solutions.count; ++k) {
        const double exact = solutions.angle[k][0];
        if (std::isnan(exact)) {  // free (on the pole): it stays
            options[n++] = q0[c];
            continue;
        }
        const double nearest = q0[c] + wrap180(exact - q0[c]);
        for (const double turn : {0.0, -360.0, 360.0}) {
            const double target = nearest + turn;
            if (!inside_limits(J, target)) continue;  // (an unbounded joint: the nearest turn)
            options[n++] = target + std::clamp(q0[c] - target, -off, off);
            break;  // the nearest turn inside the limits
        }
    }
    // The nearest (the first of equals), and the nearest clearly apart from it.
    double best = q0[c], least = 1e300, other = 0, other_least = 1e300;
    for (int i = 0; i < n; ++i)
        if (std::abs(options[i] - q0[c]) < least) least = std::abs(options[i] - q0[c]), best = options[i];
    for (int i = 0; i < n; ++i)
        if (std::abs(options[i] - best) > kPoleClearlyLess && std::abs(options[i] - q0[c]) < other_least)
            other_least = std::abs(options[i] - q0[c]), other = options[i];
    // Two options clearly apart: a branch choice, which the look-back may ask to take the other way.
    flipped = other_least < 1e300 && choices.next_flipped();
    if (flipped) best = other;
    // The tilt: the point of the great circle at that turntable angle nearest the axis
    // (cos B along the pole, sin B along the tilt at 90 degrees), taken nearest B now.
    q[c] = best;
    q[b] = 90;
    // tool_axis: forward's axis to the bit, without its translations.
    const Eigen::Vector3d toward = kin_.tool_axis(q);
    const double tilt_b = std::atan2(to.axis.dot(toward), to.axis.dot(pole)) * kDegPerRad;
    q[b] = q0[b] + wrap180(tilt_b - q0[b]);
    if (!kin_.solve_position(to.tip, q).ok() || !check_limits(machine_, q).ok()) return false;
    end_axis = kin_.tool_axis(q);
    if (angle_between(end_axis, to.axis) > budget + 1e-9) return false;
    // The usual end from an exact start: nothing to choose (planar files, exact on the pole).
    if (start_exact && std::abs(q[c] - usual[c]) < kSameAngle && std::abs(q[b] - usual[b]) < kSameAngle) return false;
    return true;
}

bool PoleHold::hold(const std::vector<double>& q0, const std::vector<double>& usual, const Pose& from, const Pose& to,
                    const Kinematics::Solutions* at_end, std::vector<double>& q, double& worst, bool need_worst, bool start_exact,
                    bool hold_end, PoleChoices& choices) {
    const std::size_t c = c_, b = b_;
    const double tolerance = machine_.motion.angle_tolerance;
    const Eigen::Vector3d start_axis = axis_at(q0);  // as passage found it (a miss computes it again)
    turn_.valid = false;
    q = usual;  // as solved: the continuous end (exact)
    Eigen::Vector3d end_axis;  // tool_axis(q), when hold_end
    bool flipped = false;
    if (hold_end && !held_end(q0, usual, to, at_end, q, end_axis, start_exact, choices, flipped)) return false;
    // A flipped choice that one joint-linear turn cannot reach within the tolerance: with the
    // look-back's leave, a half turn in place where the move passes nearest the pole.
    const bool may_turn = flipped && choices.turns;
    auto or_turn = [&] {
        if (!may_turn || !turn_between(q0, from, to, q, worst)) return false;
        remember_axis(q, end_axis);
        return true;
    };
    // The joint-linear turn from the start against the programmed axis's great circle. The first
    // point past the margin decides (worst is used only when the passage is taken, and then every
    // point was measured).
    worst = 0;
    std::vector<double>& lerp = probe_;
    lerp.resize(q0.size());
    const GreatArc arc(from.axis, to.axis);
    const double limit = kPoleMargin * tolerance;
    // The tool axis at joints p: the start's and the end's are known (tool_axis's, or the solve's
    // to rounding: see axis_at; rotaries compared to the bit), and the cache may hold others.
    const std::uint64_t c0 = std::bit_cast<std::uint64_t>(q0[c]), b0 = std::bit_cast<std::uint64_t>(q0[b]);
    auto axis_of = [&](const std::vector<double>& p) -> Eigen::Vector3d {
        const std::uint64_t pc = std::bit_cast<std::uint64_t>(p[c]), pb = std::bit_cast<std::uint64_t>(p[b]);
        if (pc == c0 && pb == b0) return start_axis;
        if (hold_end && pc == std::bit_cast<std::uint64_t>(q[c]) && pb == std::bit_cast<std::uint64_t>(q[b])) return end_axis;
        return axis_at(p);
    };
    auto deviation = [&](int i, double* chord) {
        const double t = double(i) / kPoleSamples;
        for (std::size_t j = 0; j < q.size(); ++j) lerp[j] = q0[j] + t * (q[j] - q0[j]);
        const Eigen::Vector3d axis = axis_of(lerp), ideal = arc.at(t);
        if (chord) *chord = (axis - ideal).norm();
        return angle_between(axis, ideal);
    };
    // A held end taken is the next move's start: its axis is remembered for it.
    if (need_worst) {
        for (int i = 0; i <= kPoleSamples; ++i) {
            worst = std::max(worst, deviation(i, nullptr));
            if (!(worst <= limit)) return or_turn();
        }
        if (hold_end) remember_axis(q, end_axis);
        return true;
    }
    // Without a report the verdict alone is wanted, and it is the same with fewer points: the
    // ends are measured, then the interval between two measured points is halved until it is
    // cleared. Within an interval the gap between the two curves (the joint-linear axis u and the
    // great circle g, unit vectors) stays within the larger of its ends' plus M h^2 / 8, with h
    // the interval and M a bound on |u'' - g''| over the whole turn: kinematics' bound on the
    // axis path's bend (8 times its chord distance) plus g's, the arc angle squared. An interval
    // so cleared has every point inside the margin; one of a single step has no point inside.
    // (A gap below chord_within's chord is inside the limit; a stricter test than the asin's by
    // 1e-12 of it, which at most measures an interval more: the same verdict.)
    const double bend = 8.0 * kin_.path_bound().axis_path_bound(q0.data(), q.data()) + arc.angle * arc.angle;
    const double chord_limit = chord_limit_;  // chord_within(limit - kSlack), per machine
    auto cleared = [&](auto& self, int a, int b, double chord_a, double chord_b) -> bool {
        if (b - a <= 1) return true;
        const double h = double(b - a) / kPoleSamples;
        const double gap = std::max(chord_a, chord_b) + bend * h * h / 8.0;
        if (gap < chord_limit) return true;
        const int m = (a + b) / 2;
        double chord_m;
        if (!(deviation(m, &chord_m) <= limit)) return false;
        return self(self, a, m, chord_a, chord_m) && self(self, m, b, chord_m, chord_b);
    };
    double chord0, chord1;
    if (!(deviation(0, &chord0) <= limit) || !(deviation(kPoleSamples, &chord1) <= limit)) return or_turn();
    if (!cleared(cleared, 0, kPoleSamples, chord0, chord1)) return or_turn();
    if (hold_end) remember_axis(q, end_axis);
    return true;
}

// hold's last resort (pole_policy.hpp: turn). Near the pole a turn in place moves the tool axis
// little: with the tilt t at both ends, the axis stays within about t of where it was (the
// turning joint's half turn with the tilt through zero passes the pole itself), so it is made
// where the programmed arc passes nearest the pole. Each part is checked on kPoleSamples points:
// the first and last against their stretch of the arc, the turn against the arc's point there.
bool PoleHold::turn_between(const std::vector<double>& q0, const Pose& from, const Pose& to, const std::vector<double>& q,
                            double& worst) {
    const std::size_t c = c_, b = b_;
    const double limit = kPoleMargin * machine_.motion.angle_tolerance;
    const GreatArc arc(from.axis, to.axis);
    auto tilt_at = [&](double s) {
        const Eigen::Vector3d u = arc.at(s);
        return std::min(angle_between(u, pole_), angle_between(u, -pole_));
    };
    // The closest approach, on the samples; kept off the ends so that each part carries some of
    // the move (and its E), the turn inside the printed move.
    double at = 0, least = 1e300;
    for (int i = 0; i <= kPoleSamples; ++i) {
        const double s = double(i) / kPoleSamples;
        if (const double t = tilt_at(s); t < least) least = t, at = s;
    }
    at = std::clamp(at, 1.0 / 32, 31.0 / 32);
    if (!(tilt_at(at) < limit)) return false;
    const Eigen::Vector3d u = arc.at(at);
    const Eigen::Vector3d tip = from.tip + at * (to.tip - from.tip);
    const Kinematics::Solutions solutions = kin_.orientation_solutions(u);
    // Joints at `at` with the turning joint at `a`: the tilt to the great circle's point nearest u
    // (as held_end), near `b_near`, the tip solved.
    auto joints_at = [&](double a, double b_near, std::vector<double>& p) {
        p = q0;
        p[c] = a;
        p[b] = 90;
        const Eigen::Vector3d toward = kin_.tool_axis(p);
        p[b] = b_near + wrap180(std::atan2(u.dot(toward), u.dot(pole_)) * kDegPerRad - b_near);
        return kin_.solve_position(tip, p).ok() && check_limits(machine_, p).ok();
    };
    // The turning joint before the turn: held where it starts, or on the exact angle there
    // nearest it; after: where the passage ends, or the exact angle nearest that.
    auto exact_near = [&](double a, double& out) {
        double best = 1e300;
        for (int k = 0; k < solutions.count; ++k) {
            const double e = solutions.angle[k][0];
            if (std::isnan(e)) continue;
            for (const double turn : {0.0, -360.0, 360.0}) {
                const double v = a + wrap180(e - a) + turn;
                if (inside_limits(machine_.joints[c], v) && std::abs(v - a) < std::abs(best - a)) best = v;
            }
        }
        out = best;
        return best < 1e300;
    };
    double before[2] = {q0[c], 0}, after[2] = {q[c], 0};
    const int n_before = 1 + exact_near(q0[c], before[1]), n_after = 1 + exact_near(q[c], after[1]);
    std::vector<double>& lerp = probe_;
    lerp.resize(q0.size());
    auto part = [&](const std::vector<double>& pa, const std::vector<double>& pb, double sa, double sb, double& w) {
        for (int i = 0; i <= kPoleSamples && w <= limit; ++i) {
            const double t = double(i) / kPoleSamples;
            for (std::size_t j = 0; j < pa.size(); ++j) lerp[j] = pa[j] + t * (pb[j] - pa[j]);
            w = std::max(w, angle_between(kin_.tool_axis(lerp), arc.at(sa + t * (sb - sa))));
        }
        return w <= limit;
    };
    std::vector<double> qa, qb;
    for (int i = 0; i < n_before; ++i) {
        if (!joints_at(before[i], q0[b], qa)) continue;
        double w_first = 0;
        if (!part(q0, qa, 0, at, w_first)) continue;
        for (int k = 0; k < n_after; ++k) {
            // Onto the other branch: the turning joint clearly apart, the tilt's sign the other.
            if (std::abs(after[k] - qa[c]) <= kPoleClearlyLess) continue;
            if (!joints_at(after[k], -qa[b], qb)) continue;
            double w = w_first;
            if (!part(qa, qb, at, at, w) || !part(qb, q, at, 1, w)) continue;
            turn_.valid = true;
            turn_.at = at;
            turn_.before = qa;
            turn_.after = qb;
            worst = w;
            return true;
        }
    }
    return false;
}

bool pole_crossing(const Kinematics& kin, const std::vector<double>& q0, const Eigen::Vector3d& end_tip, const GreatArc& arc,
                   const Kinematics::Solutions& solutions, bool split_ok, double measured, PoleScratch& scratch,
                   std::vector<double>& end, double& angle) {
    const Machine& machine = kin.machine();
    const auto& rot = kin.rotary_joints();
    auto rotary_distance = [&](const std::vector<double>& a, const std::vector<double>& b) {
        double d = 0;
        for (const int j : rot) d += std::abs(a[std::size_t(j)] - b[std::size_t(j)]);
        return d;
    };
    std::vector<double>& q = scratch.q;
    if (split_ok) {
        // No end on another branch clearly nearer: no, whatever the estimate says.
        bool nearer = false;
        for (int b = 0; b < solutions.count && !nearer; ++b) {
            q = q0;
            if (orient_on_branch(machine, rot, solutions, b, q0, q0, q).ok())
                nearer = rotary_distance(q, q0) < measured - kPoleClearlyLess;
        }
        if (!nearer) return false;
    }
    // How far the continuous branch turns the rotaries, estimated on a few points of the path
    // (cheap; it is measured exactly below only when another way looks shorter).
    constexpr int kEstimate = 16;
    std::vector<double>& qq = scratch.lerp;
    std::vector<double>& prev = scratch.prev;
    std::vector<double>& cur = scratch.cur;
    prev = q0;
    cur = q0;
    double stay = 0;
    for (int i = 1; i <= kEstimate; ++i) {
        if (!orient_within_limits(machine, rot, kin.orientation_solutions(arc.at(double(i) / kEstimate)), prev, prev, cur).ok())
            break;
        stay += rotary_distance(prev, cur);
        prev = cur;
    }
    bool found = false;
    double best = stay - kPoleClearlyLess;
    for (int b = 0; b < solutions.count; ++b) {
        q = q0;
        if (!orient_on_branch(machine, rot, solutions, b, q0, q0, q).ok()) continue;
        const double travel = rotary_distance(q, q0);
        if (travel >= best) continue;
        if (!kin.solve_position(end_tip, q).ok() || !check_limits(machine, q).ok()) continue;
        // The tool axis along the linear turn against its great-circle path, densely.
        double worst = 0;
        qq.resize(q.size());
        for (int i = 1; i < kPoleSamples; ++i) {
            const double t = double(i) / kPoleSamples;
            for (std::size_t j = 0; j < q.size(); ++j) qq[j] = q0[j] + t * (q[j] - q0[j]);
            const Eigen::Vector3d axis = kin.tool_axis(qq);
            worst = std::max(worst, std::acos(std::clamp(axis.dot(arc.at(t)), -1.0, 1.0)) * kDegPerRad);
        }
        if (worst > kPoleMargin * machine.motion.angle_tolerance) continue;
        best = travel;
        end = q;
        angle = worst;
        found = true;
    }
    if (!split_ok) return found;
    return found && best < measured - kPoleClearlyLess;
}

double pole_join(const Kinematics& kin, const std::vector<double>& q0, const Eigen::Vector3d& p0_tip,
                 const Eigen::Vector3d& p1_tip, const GreatArc& arc, PoleScratch& scratch, std::vector<double>& q1,
                 double& worst) {
    const Machine& machine = kin.machine();
    const double limit = kPoleMargin * machine.motion.angle_tolerance;
    std::vector<double>& lerp = scratch.lerp;
    lerp.resize(q0.size());
    // The longest first part that works: the gentlest turn. Down to 2^-12 of the move, a turn
    // almost in place: the tool axis then stays within the start's own offset, which the hold
    // kept within half the tolerance, plus the turn's small bulge.
    for (int k = 1; k <= 12; ++k) {
        const double s = std::ldexp(1.0, -k);
        const Eigen::Vector3d tip = p0_tip + s * (p1_tip - p0_tip);
        q1 = q0;
        if (!orient_within_limits(machine, kin.rotary_joints(), kin.orientation_solutions(arc.at(s)), q0, q0, q1).ok()) continue;
        if (!kin.solve_position(tip, q1).ok() || !check_limits(machine, q1).ok()) continue;
        double w = 0;
        for (int i = 1; i <= kPoleSamples && w <= limit; ++i) {
            const double t = double(i) / kPoleSamples;
            for (std::size_t j = 0; j < q0.size(); ++j) lerp[j] = q0[j] + t * (q1[j] - q0[j]);
            w = std::max(w, angle_of_dot(kin.tool_axis(lerp).dot(arc.at(t * s))));
        }
        if (w <= limit) {
            worst = w;
            return s;
        }
    }
    return 0;
}

double pole_leaving_probe(const Kinematics::Solutions& at_start, std::size_t rotaries, const Eigen::Vector3d& from,
                          const Eigen::Vector3d& to) {
    bool on_pole = false;
    for (int b = 0; b < at_start.count; ++b)
        for (std::size_t k = 0; k < rotaries; ++k) on_pole |= std::isnan(at_start.angle[b][k]);  // no branch a value
    if (!on_pole) return 0;
    const double turn_angle = std::acos(std::clamp(from.dot(to), -1.0, 1.0));
    if (!(turn_angle > 0)) return 0;
    return turn_angle > 1e-4 ? 1e-4 / turn_angle : 1.0;
}

IkResult pole_reindex(const Kinematics& kin, const std::vector<double>& q0, const std::vector<double>& probe,
                      const Eigen::Vector3d& tip, std::vector<double>& turned) {
    const Machine& machine = kin.machine();
    turned.clear();
    double jump = 0;
    for (std::size_t j = 0; j < probe.size(); ++j)
        if (machine.joints[j].rotary) jump = std::max(jump, std::abs(probe[j] - q0[j]));
    if (!(jump > 1.0)) return {};
    turned = q0;
    for (std::size_t j = 0; j < turned.size(); ++j)
        if (machine.joints[j].rotary && std::abs(probe[j] - turned[j]) > 1.0) turned[j] = probe[j];
    if (auto rp = kin.solve_position(tip, turned); !rp.ok()) return rp;
    return check_limits(machine, turned);
}

}  // namespace xlate5
