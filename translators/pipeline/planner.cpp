// SPDX-License-Identifier: GPL-3.0-or-later
// The planner stage: typed moves -> joint moves (IK, solution choice, limits, re-zero).
// What it may call: see planner.hpp.
#include "translators/pipeline/planner.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>

#include "translators/constants.hpp"
#include "translators/error.hpp"
#include "translators/kinematics/great_arc.hpp"
#include "translators/pipeline/joint_limits.hpp"
#include "translators/inspect/report.hpp"

#include <Eigen/Geometry>

namespace xlate5 {

namespace {

// Near a pole (the tool axis along the turntable's axis, which then turns it no more), the
// turntable's angle matters less the nearer the axis is: at a tilt t from the pole, turning it by
// d moves the tool axis by asin(sin t sin d). So there it need not follow the axis's azimuth,
// which swings round fast however slowly the axis moves past (a half turn for a passage that
// misses the pole by a hair, over however many short moves). Within kPoleRegion angle tolerances
// of the pole the end of each short move (turning the tool axis by less than the tolerance: a
// longer one ends exactly on its programmed axis) may leave that axis by a budget: kPoleHold of the
// tolerance up to that tilt (any turntable angle will do: it is held), falling linearly to zero
// at the region's edge, where the ends are exact again. The other half of the tolerance is left
// for the joint-linear turn between the ends, which is checked on kPoleSamples points.
// (Affouard et al.'s singularity cone with Grandguillaume et al.'s patching of C, as Isa, Koc
// 2018, sec. 4.6 uses them; here the cone is the angle tolerance and the patch bounded by it.)
constexpr double kPoleRegion = 2.0;
constexpr double kPoleHold = 0.5;
constexpr int kPoleSamples = 64;
constexpr double kPoleMargin = 0.97;  // as the motion stage's sampling margin
constexpr double kPoleSlack = 1e-9;   // degrees: rounding in pole_passage's two computations of the gap

double angle_between(const Eigen::Vector3d& a, const Eigen::Vector3d& b) { return angle_of_dot(a.dot(b)); }

}  // namespace

Planner::Planner(const Kinematics& kinematics, PlannerState& state, JointEmitter& emitter, MoveLog* log)
    : kin_(kinematics),
      machine_(kinematics.machine()),
      limits_(kinematics.machine()),
      state_(state),
      emitter_(emitter),
      log_(log),
      compensation_(kinematics.machine().compensation),
      motion_(kinematics, emitter),
      q_next_(state.q),
      pole_region_(kPoleRegion * kinematics.machine().motion.angle_tolerance),
      short_turn_(kinematics.machine().motion.angle_tolerance),
      exact_start_(least_dot_below(1e-6)),
      pole_chord_limit_(chord_within(kPoleMargin * kinematics.machine().motion.angle_tolerance - kPoleSlack)) {
    // The pole of a has_flip machine (pole_passage): the tool axis with the tilting rotary at 0,
    // which the first rotary then turns about itself (has_flip: within 1e-9 of its axis), so it is
    // the same for every joint value; computed per move before, the same to rounding (every
    // output of the comparison runs identical).
    const auto& rot = kin_.rotary_joints();
    if (rot.size() == 2 && kin_.has_flip()) {
        std::vector<double> q = machine_.home_joints();
        q[std::size_t(rot[1])] = 0;
        pole_ = kin_.tool_axis(q);
    }
    pole_checks_ = rot.size() == 2 && kin_.has_flip() && machine_.motion.segment;
    if (pole_checks_) pole_c_ = std::size_t(rot[0]), pole_b_ = std::size_t(rot[1]);
}

// The tool axis at q's rotaries: a remembered one when they are the same to the bit (a move's
// end is the next one's start), else tool_axis(q). pole_passage's machines only (two rotaries).
// The older slot first: it holds the end of the move before, this move's start (the newer one
// holds this move's usual end). The remembered axes are the position solve's, computed from the
// rotaries alone (rotations; the linear joints only translate): tool_axis(q) to the bit, or to
// rounding where the solve took the rotaries' sines from the orientation solve (a two-turn
// table's closed form); either way the slots are tried in a fixed order, so the answer is the
// same on every run.
inline Eigen::Vector3d Planner::axis_at(const std::vector<double>& q) const {
    const std::uint64_t qc = std::bit_cast<std::uint64_t>(q[pole_c_]), qb = std::bit_cast<std::uint64_t>(q[pole_b_]);
    const KnownAxis& older = known_axes_[known_next_];
    if (older.holds(qc, qb)) return older.axis;
    const KnownAxis& newer = known_axes_[1 - known_next_];
    if (newer.holds(qc, qb)) return newer.axis;
    return kin_.tool_axis(q);
}

void Planner::remember_axis(const std::vector<double>& q, const Eigen::Vector3d& axis) {
    // Two slots: a move's end is remembered before the pole check asks for its start (the end
    // of the move before). Called only where pole_passage applies (two rotaries).
    KnownAxis& k = known_axes_[known_next_];
    known_next_ = 1 - known_next_;
    k.rotary[0] = std::bit_cast<std::uint64_t>(q[pole_c_]);
    k.rotary[1] = std::bit_cast<std::uint64_t>(q[pole_b_]);
    k.axis = axis;
    k.valid = true;
}

void Planner::plain_image() {
    state_.image = {};
    for (std::size_t k = 0; k < kin_.rotary_joints().size(); ++k) state_.image.shift[k] = -state_.rezeroed[k];
}

void Planner::forget_rezeros(const std::vector<bool>& which) {
    const auto& rot = kin_.rotary_joints();
    for (std::size_t k = 0; k < rot.size(); ++k)
        if (which[std::size_t(rot[k])]) state_.rezeroed[k] = 0;
}

void Planner::map_angles(const AngleImage& image, const std::vector<double>& a, std::vector<double>& q) const {
    const auto& rot = kin_.rotary_joints();
    for (std::size_t k = 0; k < rot.size(); ++k) {
        const std::size_t j = std::size_t(rot[k]);
        q[j] = image.sign[k] * a[j] + image.shift[k];
    }
}

void Planner::unmap_angles(const AngleImage& image, const std::vector<double>& q, std::vector<double>& a) const {
    const auto& rot = kin_.rotary_joints();
    for (std::size_t k = 0; k < rot.size(); ++k) {
        const std::size_t j = std::size_t(rot[k]);
        a[j] = (q[j] - image.shift[k]) * image.sign[k];
    }
}

// Where else a travel move to `end` may stop: every solution of that pose inside the limits
// other than `usual` (the continuous one), nearest the current joints first. Under G43.4 each is
// an image of the programmed angles (another turn, or the flipped branch), so the moves after it
// keep their programmed interpolation.
void Planner::end_candidates(OrientationMode mode, const Pose& end, const std::vector<double>& programmed,
                             const std::vector<double>& usual) {
    candidates_.clear();
    const auto& rot = kin_.rotary_joints();
    if (rot.empty()) return;
    const std::vector<double>& q_now = state_.q;
    auto same = [&](const std::vector<double>& a, const std::vector<double>& b) {
        for (const int j : rot)
            if (std::abs(a[std::size_t(j)] - b[std::size_t(j)]) > kSameAngle) return false;
        return true;
    };
    std::vector<double> q;
    auto consider = [&](const AngleImage& image) {
        if (!kin_.solve_position(end.tip, q).ok() || !check_limits(machine_, q).ok() || same(q, usual)) return;
        for (const Candidate& c : candidates_)
            if (same(c.q, q)) return;
        candidates_.push_back({q, image});
    };
    const int turns1 = rot.size() > 1 ? 2 : 0;
    if (mode == OrientationMode::Angles) {
        for (const bool flip : {false, true}) {
            if (flip && !kin_.has_flip()) continue;
            AngleImage base;
            base.sign[1] = flip ? -1 : 1;
            base.shift[0] = flip ? 180 : 0;
            // Turns counted from the one nearest the current joints.
            double centre[2];
            for (std::size_t k = 0; k < rot.size(); ++k) {
                const std::size_t j = std::size_t(rot[k]);
                centre[k] = std::round((q_now[j] - (base.sign[k] * programmed[j] + base.shift[k])) / 360.0);
            }
            for (int t0 = -2; t0 <= 2; ++t0)
                for (int t1 = -turns1; t1 <= turns1; ++t1) {
                    AngleImage image = base;
                    image.shift[0] += 360.0 * (centre[0] + t0);
                    if (rot.size() > 1) image.shift[1] += 360.0 * (centre[1] + t1);
                    q = usual;
                    map_angles(image, programmed, q);
                    consider(image);
                }
        }
    } else {
        const auto solutions = kin_.orientation_solutions(end.axis);
        for (int b = 0; b < solutions.count; ++b)
            for (int t0 = -2; t0 <= 2; ++t0)
                for (int t1 = -turns1; t1 <= turns1; ++t1) {
                    q = usual;
                    for (std::size_t k = 0; k < rot.size(); ++k) {
                        const std::size_t j = std::size_t(rot[k]);
                        const double sol = solutions.angle[b][k];
                        if (std::isnan(sol)) continue;  // free at a pole: it stays
                        q[j] = q_now[j] + wrap180(sol - q_now[j]) + 360.0 * (k == 0 ? t0 : t1);
                    }
                    consider(state_.image);
                }
    }
    auto distance = [&](const Candidate& c) {
        double d = 0;
        for (const int j : rot) d += (c.q[std::size_t(j)] - q_now[std::size_t(j)]) * (c.q[std::size_t(j)] - q_now[std::size_t(j)]);
        return d;
    };
    std::stable_sort(candidates_.begin(), candidates_.end(), [&](const Candidate& a, const Candidate& b) { return distance(a) < distance(b); });
}

// The tests every move makes, cheapest first; most moves leave here (see pole_hold). Small, so
// that tool_move takes it inline.
inline bool Planner::pole_passage(const Pose& from, const Pose& to, const Kinematics::Solutions* at_end, std::vector<double>& q,
                                  double& worst, bool need_worst) {
    // Machines whose tool axis at zero lies along the first rotary (has_flip): there the pole is
    // that rotary's axis and the second tilts the tool along a great circle through it.
    if (!pole_checks_) return false;
    const std::size_t c = pole_c_, b = pole_b_;
    const std::vector<double>& q0 = state_.q;
    const bool start_exact = axis_at(q0).dot(from.axis) >= exact_start_;
    start_held_ = !start_exact;
    // From an exact start, a move whose usual end turns no rotary has nothing to hold (planar
    // files under G43.5: the axis stays on the pole).
    if (start_exact && q_next_[c] == q0[c] && q_next_[b] == q0[b]) return false;
    // The tilt from the pole (the nearer of its two ends) is below the region; its value is
    // needed only then. The dot with -pole is -d to the bit (each product and sum only changes
    // sign; a zero sum's sign aside, which neither comparison nor acos tells apart).
    const double d = to.axis.dot(pole_);
    const bool near_pole = pole_region_.below(d) || pole_region_.below(-d);
    if (start_exact && !near_pole) return false;
    // Only a move turning the tool axis by less than the tolerance may end off its axis: a
    // passage made of such moves cannot cross in any one of them. A longer move ends exactly
    // where it was programmed (a crossing within it is the motion stage's).
    const bool short_move = short_turn_.below(from.axis.dot(to.axis));
    if (start_exact && !short_move) return false;
    return pole_hold(from, to, at_end, q, worst, need_worst, start_exact, near_pole && short_move);
}

// The rest of pole_passage, out of line: a move near the pole, or from an inexact start.
bool Planner::pole_hold(const Pose& from, const Pose& to, const Kinematics::Solutions* at_end, std::vector<double>& q,
                        double& worst, bool need_worst, bool start_exact, bool hold_end) {
    const std::size_t c = pole_c_, b = pole_b_;
    const std::vector<double>& q0 = state_.q;
    const double tolerance = machine_.motion.angle_tolerance;
    const double region = kPoleRegion * tolerance, hold = kPoleHold * tolerance;
    const Eigen::Vector3d& pole = pole_;
    const Eigen::Vector3d start_axis = axis_at(q0);  // as pole_passage found it (a miss computes it again)
    q = q_next_;  // as solved: the continuous end (exact)
    Eigen::Vector3d end_axis;  // tool_axis(q), when hold_end
    if (hold_end) {
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
        double best = q0[c], least = 1e300;
        for (int k = 0; k < solutions.count; ++k) {
            const double exact = solutions.angle[k][0];
            if (std::isnan(exact)) {  // free (on the pole): it stays
                least = 0;
                best = q0[c];
                continue;
            }
            const double nearest = q0[c] + wrap180(exact - q0[c]);
            for (const double turn : {0.0, -360.0, 360.0}) {
                const double target = nearest + turn;
                if (!inside_limits(J, target)) continue;  // (an unbounded joint: the nearest turn)
                const double value = target + std::clamp(q0[c] - target, -off, off);
                if (std::abs(value - q0[c]) < least) {
                    least = std::abs(value - q0[c]);
                    best = value;
                }
                break;  // the nearest turn inside the limits
            }
        }
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
        if (start_exact && std::abs(q[c] - q_next_[c]) < kSameAngle && std::abs(q[b] - q_next_[b]) < kSameAngle) return false;
    }
    // The joint-linear turn from the start against the programmed axis's great circle. The first
    // point past the margin decides (worst is used only when the passage is taken, and then every
    // point was measured).
    worst = 0;
    std::vector<double>& lerp = pole_probe_;
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
            if (!(worst <= limit)) return false;
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
    const double bend = 8.0 * kin_.axis_path_bound(q0.data(), q.data()) + arc.angle * arc.angle;
    const double chord_limit = pole_chord_limit_;  // chord_within(limit - kSlack), per machine
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
    if (!(deviation(0, &chord0) <= limit) || !(deviation(kPoleSamples, &chord1) <= limit)) return false;
    if (!cleared(cleared, 0, kPoleSamples, chord0, chord1)) return false;
    if (hold_end) remember_axis(q, end_axis);
    return true;
}

void Planner::tool_move(const ToolMove& mv, LineRun& run, std::string& out) {
    PlannerState& s = state_;
    copy_joints(q_next_, s.q);
    if (mv.any_rotary) map_angles(s.image, *mv.angles, q_next_);
    end_solved_.valid = false;
    ChosenSolution chosen;  // the solution the rotaries take (a tool vector's): the solve reuses its terms
    // Returned in place (prvalues): no result moved in, nor its message.
    IkResult r = [&] {
        if (!mv.any_ijk) return IkResult{};
        end_solutions_ = kin_.orientation_solutions(mv.axis);
        motion_.remember_solutions(end_solutions_);  // the move's end axis: the motion stage asks for it again
        return orient_within_limits(machine_, kin_.rotary_joints(), end_solutions_, s.q, s.q, q_next_, &chosen);
    }();
    Pose next = s.pose;
    if (r.ok()) {
        if (!mv.any_xyz && !s.tip_known) {
            // Before the program has placed the tip (start, after G28) a rotary-only move turns
            // the rotaries and leaves the linear joints, as Andersons' start code (Twente 2023) expects.
            next = kin_.forward(q_next_);
        } else {
            next.tip = mv.tip;
            if (mv.mode == OrientationMode::Vector && pole_checks_) {
                // The tool axis of the end comes with the solve at little cost: the pole check
                // asks for it at the next move's start.
                Eigen::Vector3d at_end;
                // r is ok here: only a failure needs moving in.
                if (auto solved = kin_.solve_position(next.tip, q_next_, &at_end, &end_solved_, chosen); solved.ok())
                    remember_axis(q_next_, at_end);
                else
                    r = std::move(solved);
                if (mv.any_rotary) next.axis = at_end;
            } else if (auto solved = kin_.solve_position(next.tip, q_next_, mv.any_rotary ? &next.axis : nullptr, &end_solved_, chosen); !solved.ok()) {
                r = std::move(solved);  // r is ok here: only a failure needs moving in
            }
            if (mv.any_ijk) next.axis = mv.axis;
        }
    }
    if (r.ok() && !limits_.contains(q_next_)) r = check_limits(machine_, q_next_);
    // A travel move (tool space, no extrusion) may end on another solution of its pose: when its
    // usual end is outside a joint's limits, or when the look-back replays it to unwind a joint
    // for the printing that follows. Printing moves never change solution: their path is printed.
    const bool tool_space = mv.any_xyz || s.tip_known;
    const bool prints = mv.e && (mv.e_relative ? mv.e->value != 0 : mv.e->value != mv.e_position);
    const bool travel = tool_space && !prints && (mv.any_xyz || mv.any_rotary || mv.any_ijk);
    run.travels = run.travels || travel;
    bool unwind = false;
    SolutionChange change = SolutionChange::None;
    const int forced = travel ? run.end_candidate : -1;
    if (travel) run.end_candidate = -1;
    if (travel && (forced >= 0 || (!r.ok() && r.status == IkStatus::OutOfLimits))) {
        end_candidates(mv.mode, next, *mv.angles, q_next_);
        const std::size_t k = forced >= 0 ? std::size_t(forced) : 0;
        if (k < candidates_.size()) {
            // For the report: whole turns of the rotaries from the usual end are an unwind,
            // anything else the other orientation branch.
            change = SolutionChange::Turns;
            for (std::size_t j = 0; j < q_next_.size(); ++j) {
                if (!machine_.joints[j].rotary) continue;
                const double d = candidates_[k].q[j] - q_next_[j];
                if (!(std::abs(d - 360.0 * std::round(d / 360.0)) < 1e-6)) change = SolutionChange::Branch;
            }
            q_next_ = candidates_[k].q;
            if (mv.mode == OrientationMode::Angles) s.image = candidates_[k].image;
            unwind = true;
            r = {};
        } else if (forced >= 0) {
            run.candidate_missing = true;
            throw LineError(mv.column, "no other solution of this pose inside the limits");
        }
    }
    if (!r.ok()) {
        run.hit_limit = r.status == IkStatus::OutOfLimits;
        run.linear_limit = run.hit_limit && r.linear;
        throw LineError(mv.column, r.message);
    }
    // Near a pole the end may be chosen across moves (see pole_passage): rotaries turn linearly.
    bool passage = false;
    double passage_angle = 0;
    start_held_ = false;
    if (!unwind && mv.mode == OrientationMode::Vector && (mv.any_xyz || s.tip_known) && pole_passage(s.pose, next, mv.any_ijk ? &end_solutions_ : nullptr, pole_q_, passage_angle, log_ != nullptr)) {
        passage = true;
        q_next_ = pole_q_;
    }
    MoveSpec spec;
    spec.gcode = mv.gcode;
    // Before the program has placed the tip, the move is a joint move (one piece, F as written).
    spec.mode = (!mv.any_xyz && !s.tip_known) ? OrientationMode::Joints : mv.mode;
    spec.q0 = &s.q;
    spec.p0 = s.pose;
    spec.q1 = &q_next_;
    spec.p1 = next;
    spec.end = &end_solved_;  // the stage uses it only while its joints are still q_next_'s
    spec.commanded = mv.commanded;
    spec.e = mv.e;
    spec.e_relative = mv.e_relative;
    spec.e_start = mv.e_position;
    spec.feed = mv.feed;
    spec.f = mv.f;
    spec.inverse_time = mv.inverse_time && mv.f ? mv.f->value : 0.0;
    // An unwinding travel move turns the rotaries linearly from their start to the chosen end
    // (angle form) while the split holds the tip on the straight travel line, rather than
    // reorienting in place at one end: the tip never leaves the path the slicer planned for it
    // (usually lifted clear of the part), no end of a printed bead gets a hot nozzle sweeping
    // round on it, and each rotary moves monotonically between two values inside its limits.
    // For a branch flip (rw2: A by 180 degrees, B to -B) the tool passes upright (B = 0) on the
    // way instead of sweeping a full turn at its printing tilt.
    if (unwind || passage) spec.mode = OrientationMode::Angles;
    spec.start_held = start_held_ && !passage;
    MoveResult* measured = log_ && spec.mode != OrientationMode::Joints ? &move_result_ : nullptr;
    move_result_.pole_crossings = 0;  // set by the move that crosses, not kept from an earlier one
    auto res = motion_.emit(spec, out, measured);
    if (!res.ok() && res.status == IkStatus::OutOfLimits && travel && !unwind && spec.mode == OrientationMode::Vector) {
        // The continuous path of this travel move leaves the limits, though its end (the
        // solution nearest the start inside them) does not: turn there in angle form instead.
        spec.mode = OrientationMode::Angles;
        unwind = true;
        res = motion_.emit(spec, out, measured);
    }
    if (!res.ok()) {
        run.hit_limit = res.status == IkStatus::OutOfLimits;
        run.linear_limit = run.hit_limit && res.linear;
        throw LineError(mv.column, res.message);
    }
    if (measured) {
        measured->prints = prints;
        bound_rotary_travel(next.axis);
        measured->change = change;
        measured->moves_written = emitter_.moves_written();
        if (passage) {
            // The split measures the tip only in angle form: the axis as checked above.
            measured->angle_error = std::max(measured->angle_error, passage_angle);
            const std::size_t b = std::size_t(kin_.rotary_joints()[1]);
            if (s.q[b] * q_next_[b] < 0) measured->pole_crossings = 1;  // the tilt changed sign: the other branch
        }
    }
    if (const std::vector<double>* moved = motion_.final_joints_moved(); moved && spec.mode == OrientationMode::Vector) q_next_ = *moved;
    // An unbounded rotary that has wound far from zero is re-zeroed at the end of a travel move
    // (no extrusion), where a G92 cannot disturb a printed line: firmware without wrapping
    // (Marlin, soft endstops) then never runs out of range.
    // The program's angles are unchanged by it: under G43.4 the image takes the turns removed, so
    // the next programmed angle is written in the re-zeroed frame (the table turns as programmed).
    int rezeros = 0;
    if (!prints) {  // under absolute E, E0 after E5 extrudes (backwards): only an unchanged E does not
        const auto& rot = kin_.rotary_joints();
        for (std::size_t k = 0; k < rot.size(); ++k) {
            const std::size_t j = std::size_t(rot[k]);
            const Joint& J = machine_.joints[j];
            if (J.rezero_beyond <= 0 || std::abs(q_next_[j]) <= J.rezero_beyond) continue;
            const double turns = std::round(q_next_[j] / 360.0);
            which_.assign(q_next_.size(), false);
            which_[j] = true;
            q_next_[j] -= 360.0 * turns;
            s.image.shift[k] -= 360.0 * turns;
            s.rezeroed[k] += 360.0 * turns;
            send_joints(which_, std::nullopt, q_next_, out);
            ++rezeros;
        }
    }
    // The move's events are logged whole, with its re-zeros.
    if (measured) {
        measured->rezeros = rezeros;
        log_->add(run.line_no, *measured);
    } else if (log_ && rezeros > 0) {
        log_->add_rezeros(run.line_no, emitter_.moves_written(), rezeros);
    }
    s.q.swap(q_next_);
    s.pose = next;
    s.tip_known = s.tip_known || mv.any_xyz;
}

// A lower bound on the rotary travel of any plan whose moves end on their programmed axes, but
// within the pole region, where an end may be held off it by up to kPoleHold of the tolerance
// (as this planner's are): the report's, with the travel's ratio to it. There the tilt joint
// ends within that of one of the axis's exact solutions and the turning one within
// asin(sin hold / sin tilt) of it (any angle at a tilt below the hold); the joints travel at
// least the distance between consecutive ends. The least sum of those distances, each taken
// less both ends' slacks, over every choice of solution per move (two per axis: a dynamic
// programme over the moves) is at most any plan's travel. An unbounded turning joint is taken
// on its nearest turn.
void Planner::bound_rotary_travel(const Eigen::Vector3d& axis) {
    const auto& rot = kin_.rotary_joints();
    if (rot.size() != 2 || !kin_.has_flip()) return;
    PlannerState::RotaryBound& d = state_.bound;
    const std::size_t c = std::size_t(rot[0]), b = std::size_t(rot[1]);
    const Joint& Jc = machine_.joints[c];
    const Joint& Jb = machine_.joints[b];
    if (d.n == 0) {  // from where the machine is
        d.n = 1;
        d.best[0] = 0;
        d.c[0] = state_.q[c];
        d.b[0] = state_.q[b];
        d.slack_c = d.slack_b = 0;
    }
    const double tol = machine_.motion.angle_tolerance, hold = kPoleHold * tol;
    const double tilt = std::min(angle_between(axis, pole_), angle_between(axis, -pole_));
    const double st = std::sin(tilt / kDegPerRad), sh = std::sin(hold / kDegPerRad);
    const bool region = tilt < kPoleRegion * tol;
    const double slack_c = !region ? 0.0 : st > sh ? std::asin(sh / st) * kDegPerRad : 180.0, slack_b = region ? hold : 0.0;
    const Kinematics::Solutions solutions = kin_.orientation_solutions(axis);
    PlannerState::RotaryBound next;
    for (int k = 0; k < solutions.count && next.n < 2; ++k) {
        const double nc = solutions.angle[k][0], nb = solutions.angle[k][1];
        if (!inside_limits(Jb, nb) || (!std::isnan(nc) && Jc.bounded() && !inside_limits(Jc, nc))) continue;
        double least = 1e300;
        for (int i = 0; i < d.n; ++i) {
            double dc = 0;
            if (!std::isnan(nc) && !std::isnan(d.c[i])) dc = Jc.bounded() ? std::abs(nc - d.c[i]) : std::abs(wrap180(nc - d.c[i]));
            const double cost = std::max(0.0, dc - slack_c - d.slack_c) + std::max(0.0, std::abs(nb - d.b[i]) - slack_b - d.slack_b);
            least = std::min(least, d.best[i] + cost);
        }
        next.best[next.n] = least;
        next.c[next.n] = nc;
        next.b[next.n] = nb;
        ++next.n;
    }
    if (next.n == 0) return;  // no solution inside the limits: the move is refused anyway
    next.slack_c = slack_c;
    next.slack_b = slack_b;
    d = next;
    log_->set_rotary_bound(std::min(d.best[0], d.n > 1 ? d.best[1] : 1e300));
}

void Planner::send_joints(const std::vector<bool>& which, const std::optional<PassedNumber>& e, const std::vector<double>& q,
                          std::string& out) {
    const auto sent = compensation_.apply(q);
    if (!sent.ok()) throw LineError(1, sent.why());
    emitter_.set_position(out, q, sent.sent, which, e);
}

void Planner::joint_move(const JointMove& mv, std::string& out) {
    if (auto r = check_limits(machine_, *mv.q); !r.ok()) throw LineError(mv.column, r.message);
    state_.q.assign(mv.q->begin(), mv.q->end());
    state_.pose = kin_.forward(state_.q);
    state_.tip_known = state_.tip_known || mv.any_linear;
    const auto sent = compensation_.apply(state_.q);
    if (!sent.ok()) throw LineError(1, sent.why());
    // Under G93 every move keeps its F.
    emitter_.move(out, mv.gcode, state_.q, sent.sent, *mv.commanded, mv.e, mv.f, mv.inverse_time);
}

void Planner::set_joints(const std::vector<bool>& which, const std::vector<double>& values, bool pose_from_joints) {
    bool any = false;
    for (std::size_t j = 0; j < which.size(); ++j) {
        if (!which[j]) continue;
        state_.q[j] = values[j];
        any = true;
    }
    // The program and the firmware now agree on the joints named.
    forget_rezeros(which);
    if (any) plain_image();
    // The machine did not move: its true pose follows from the joints it now says it is at.
    if (pose_from_joints) state_.pose = kin_.forward(state_.q);
}

void Planner::send_position(const std::vector<bool>& which, const std::optional<PassedNumber>& e, std::string& out) {
    send_joints(which, e, state_.q, out);
}

void Planner::home(const std::vector<bool>& which) {
    for (std::size_t j = 0; j < state_.q.size(); ++j)
        if (which[j]) state_.q[j] = machine_.joints[j].home;
    forget_rezeros(which);
    plain_image();
    state_.tip_known = false;
    state_.pose = kin_.forward(state_.q);
    emitter_.invalidate(state_.q);
}

void Planner::moved_to(const std::vector<double>& q) {
    state_.q.assign(q.begin(), q.end());
    state_.pose = kin_.forward(state_.q);
    emitter_.invalidate(state_.q);
}

void Planner::position_unknown() { emitter_.invalidate(state_.q); }

void Planner::feed_mode_sent(bool inverse_time) { emitter_.feed_mode_sent(inverse_time); }

}  // namespace xlate5
