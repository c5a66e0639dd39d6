// SPDX-License-Identifier: GPL-3.0-or-later
// The planner stage: typed moves -> joint moves (IK, solution choice, limits, re-zero).
// What it may call: see planner.hpp.
#include "translators/pipeline/planner.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <vector>

#include "translators/constants.hpp"
#include "translators/error.hpp"
#include "translators/kinematics/great_arc.hpp"
#include "translators/pipeline/joint_limits.hpp"
#include "translators/inspect/report.hpp"

#include <Eigen/Geometry>

namespace xlate5 {

namespace {

double angle_between(const Eigen::Vector3d& a, const Eigen::Vector3d& b) { return angle_of_dot(a.dot(b)); }

}  // namespace

Planner::Planner(const Kinematics& kinematics, PlannerState& state, MoveLog* log)
    : kin_(kinematics),
      limits_(kinematics.machine()),
      state_(state),
      log_(log),
      q_next_(state.q),
      pole_hold_(kinematics),
      angle_map_{kinematics.rotary_joints()} {}

void AngleMap::plain(PlannerState& s) const {
    s.image = {};
    for (std::size_t k = 0; k < rot.size(); ++k) s.image.shift[k] = -s.rezeroed[k];
}

void AngleMap::forget_rezeros(PlannerState& s, JointBits which) const {
    for (std::size_t k = 0; k < rot.size(); ++k)
        if (which >> rot[k] & 1u) s.rezeroed[k] = 0;
}

void AngleMap::map(const AngleImage& image, const Joints& a, std::vector<double>& q) const {
    for (std::size_t k = 0; k < rot.size(); ++k) {
        const std::size_t j = std::size_t(rot[k]);
        q[j] = image.sign[k] * a[j] + image.shift[k];
    }
}

void AngleMap::unmap(const AngleImage& image, const std::vector<double>& q, Joints& a) const {
    for (std::size_t k = 0; k < rot.size(); ++k) {
        const std::size_t j = std::size_t(rot[k]);
        a[j] = (q[j] - image.shift[k]) * image.sign[k];
    }
}

namespace {

// Where else a travel move to `end` may stop: every solution of that pose inside the limits
// other than `usual` (the continuous one), nearest the current joints first. Under G43.4 each is
// an image of the programmed angles (another turn, or the flipped branch), so the moves after it
// keep their programmed interpolation.
void end_candidates(const Kinematics& kin, const AngleMap& angles, const PlannerState& state, OrientationMode mode, const Pose& end,
                    const Joints& programmed, const std::vector<double>& usual, std::vector<EndCandidate>& candidates) {
    const Machine& machine = kin.machine();
    candidates.clear();
    const auto& rot = kin.rotary_joints();
    if (rot.empty()) return;
    const std::vector<double>& q_now = state.q;
    auto same = [&](const std::vector<double>& a, const std::vector<double>& b) {
        for (const int j : rot)
            if (std::abs(a[std::size_t(j)] - b[std::size_t(j)]) > kSameAngle) return false;
        return true;
    };
    std::vector<double> q;
    auto consider = [&](const AngleImage& image) {
        if (!kin.solve_position(end.tip, q).ok() || !check_limits(machine, q).ok() || same(q, usual)) return;
        for (const EndCandidate& c : candidates)
            if (same(c.q, q)) return;
        candidates.push_back({q, image});
    };
    const int turns1 = rot.size() > 1 ? 2 : 0;
    if (mode == OrientationMode::Angles) {
        for (const bool flip : {false, true}) {
            if (flip && !kin.has_flip()) continue;
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
                    angles.map(image, programmed, q);
                    consider(image);
                }
        }
    } else {
        const auto solutions = kin.orientation_solutions(end.axis);
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
                    consider(state.image);
                }
    }
    auto distance = [&](const EndCandidate& c) {
        double d = 0;
        for (const int j : rot) d += (c.q[std::size_t(j)] - q_now[std::size_t(j)]) * (c.q[std::size_t(j)] - q_now[std::size_t(j)]);
        return d;
    };
    std::stable_sort(candidates.begin(), candidates.end(), [&](const EndCandidate& a, const EndCandidate& b) { return distance(a) < distance(b); });
}

// The planned move handed to the motion stage, from the current joints and pose (`s`) to q1,
// next; `solutions` are the end axis's (when the move gives I J K). Its `end` (the position
// solve's) is left as the solve wrote it.
inline void plan_move(const ToolMove& mv, const PlannerState& s, const Pose& next, const std::vector<double>& q1,
                      const Kinematics::Solutions& solutions, PlannedMove& spec) {
    spec.gcode = mv.gcode;
    // Before the program has placed the tip, the move is a joint move (one piece, F as written).
    spec.mode = (!mv.any_xyz && !s.tip_known) ? OrientationMode::Joints : mv.mode;
    set_joints(spec.q0, s.q);
    spec.p0 = s.pose;
    set_joints(spec.q1, q1);
    spec.p1 = next;
    if (mv.any_ijk) spec.end_solutions = solutions;  // the motion stage asks for them again
    else spec.end_solutions.reset();
    spec.commanded = mv.commanded;
    spec.e = mv.e;
    spec.e_relative = mv.e_relative;
    spec.e_start = mv.e_position;
    spec.feed = mv.feed;
    spec.f = mv.f;
    spec.inverse_time = mv.inverse_time && mv.f ? mv.f->value : 0.0;
    spec.start_held = false;
    spec.turn.valid = false;
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
// Advanced by a move ending on `axis` (pole: the pole's axis): false when the bound does not
// apply (not two rotaries with the flip) or the axis has no solution inside the limits.
bool bound_rotary_travel(const Kinematics& kin, const Eigen::Vector3d& pole, PlannerState& state, const Eigen::Vector3d& axis,
                         double& bound) {
    const Machine& machine = kin.machine();
    const auto& rot = kin.rotary_joints();
    if (rot.size() != 2 || !kin.has_flip()) return false;
    PlannerState::RotaryBound& d = state.bound;
    const std::size_t c = std::size_t(rot[0]), b = std::size_t(rot[1]);
    const Joint& Jc = machine.joints[c];
    const Joint& Jb = machine.joints[b];
    if (d.n == 0) {  // from where the machine is
        d.n = 1;
        d.best[0] = 0;
        d.c[0] = state.q[c];
        d.b[0] = state.q[b];
        d.slack_c = d.slack_b = 0;
    }
    const double tol = machine.motion.angle_tolerance, hold = kPoleHold * tol;
    const double tilt = std::min(angle_between(axis, pole), angle_between(axis, -pole));
    const double st = std::sin(tilt / kDegPerRad), sh = std::sin(hold / kDegPerRad);
    const bool region = tilt < kPoleRegion * tol;
    const double slack_c = !region ? 0.0 : st > sh ? std::asin(sh / st) * kDegPerRad : 180.0, slack_b = region ? hold : 0.0;
    const Kinematics::Solutions solutions = kin.orientation_solutions(axis);
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
    if (next.n == 0) return false;  // no solution inside the limits: the move is refused anyway
    next.slack_c = slack_c;
    next.slack_b = slack_b;
    d = next;
    bound = std::min(d.best[0], d.n > 1 ? d.best[1] : 1e300);
    return true;
}

}  // namespace


// The usual end of a tool-space move: its joints in q_next_ (the continuous solution), its pose
// in `next`; not ok when it cannot be reached or lies outside the limits.
inline IkResult Planner::solve_end(const ToolMove& mv, Pose& next) {
    PlannerState& s = state_;
    q_next_ = s.q;
    if (mv.any_rotary) angle_map_.map(s.image, mv.angles, q_next_);
    plan_.move.end.valid = false;
    ChosenSolution chosen;  // the solution the rotaries take (a tool vector's): the solve reuses its terms
    // Returned in place (prvalues): no result moved in, nor its message.
    IkResult r = [&] {
        if (!mv.any_ijk) return IkResult{};
        end_solutions_ = kin_.orientation_solutions(mv.axis);
        return orient_within_limits(kin_.machine(), kin_.rotary_joints(), end_solutions_, s.q, s.q, q_next_, &chosen);
    }();
    next = s.pose;
    if (r.ok()) {
        if (!mv.any_xyz && !s.tip_known) {
            // Before the program has placed the tip (start, after G28) a rotary-only move turns
            // the rotaries and leaves the linear joints, as Andersons' start code (Twente 2023) expects.
            next = kin_.forward(q_next_);
        } else {
            next.tip = mv.tip;
            if (mv.mode == OrientationMode::Vector && pole_hold_.applies()) {
                // The tool axis of the end comes with the solve at little cost: the pole check
                // asks for it at the next move's start.
                Eigen::Vector3d at_end;
                // r is ok here: only a failure needs moving in.
                if (auto solved = kin_.solve_position(next.tip, q_next_, &at_end, &plan_.move.end, chosen); solved.ok())
                    pole_hold_.remember_axis(q_next_, at_end);
                else
                    r = std::move(solved);
                if (mv.any_rotary) next.axis = at_end;
            } else if (auto solved = kin_.solve_position(next.tip, q_next_, mv.any_rotary ? &next.axis : nullptr, &plan_.move.end, chosen); !solved.ok()) {
                r = std::move(solved);  // r is ok here: only a failure needs moving in
            }
            if (mv.any_ijk) next.axis = mv.axis;
        }
    }
    if (r.ok() && !limits_.contains(q_next_)) r = check_limits(kin_.machine(), q_next_);
    return r;
}

// A travel move (tool space, no extrusion) may end on another solution of its pose: when its
// usual end is outside a joint's limits, or when the look-back replays it to unwind a joint for
// the printing that follows. Printing moves never change solution: their path is printed.
// Returns true when it does (q_next_ is then that end), with the kind of change for the report.
inline bool Planner::other_end(const ToolMove& mv, const Pose& next, bool travel, IkResult& r, LineRun& run, SolutionChange& change) {
    const int forced = travel ? run.end_candidate : -1;
    if (travel) run.end_candidate = -1;
    if (!travel || !(forced >= 0 || (!r.ok() && r.status == IkStatus::OutOfLimits))) return false;
    end_candidates(kin_, angle_map_, state_, mv.mode, next, mv.angles, q_next_, candidates_);
    const std::size_t k = forced >= 0 ? std::size_t(forced) : 0;
    if (k >= candidates_.size()) {
        if (forced < 0) return false;
        run.candidate_missing = true;
        throw LineError(mv.column, "no other solution of this pose inside the limits");
    }
    // For the report: whole turns of the rotaries from the usual end are an unwind, anything
    // else the other orientation branch.
    change = SolutionChange::Turns;
    for (std::size_t j = 0; j < q_next_.size(); ++j) {
        if (!kin_.machine().joints[j].rotary) continue;
        const double d = candidates_[k].q[j] - q_next_[j];
        if (!(std::abs(d - 360.0 * std::round(d / 360.0)) < 1e-6)) change = SolutionChange::Branch;
    }
    q_next_ = candidates_[k].q;
    if (mv.mode == OrientationMode::Angles) state_.image = candidates_[k].image;
    r = {};
    return true;
}

// An unbounded rotary that has wound far from zero is re-zeroed at the end of a travel move (no
// extrusion), where a G92 cannot disturb a printed line: firmware without wrapping (Marlin, soft
// endstops) then never runs out of range. The program's angles are unchanged by it: under G43.4
// the image takes the turns removed, so the next programmed angle is written in the re-zeroed
// frame (the table turns as programmed). Returns the G92s to write (in rezeros_), one per joint
// in turn, each with the joints as re-zeroed so far.
int Planner::rezero() {
    PlannerState& s = state_;
    int rezeros = 0;
    const auto& rot = kin_.rotary_joints();
    for (std::size_t k = 0; k < rot.size(); ++k) {
        const std::size_t j = std::size_t(rot[k]);
        const Joint& J = kin_.machine().joints[j];
        if (J.rezero_beyond <= 0 || std::abs(q_next_[j]) <= J.rezero_beyond) continue;
        const double turns = std::round(q_next_[j] / 360.0);
        q_next_[j] -= 360.0 * turns;
        s.image.shift[k] -= 360.0 * turns;
        s.rezeroed[k] += 360.0 * turns;
        SetJoints& g92 = rezeros_[std::size_t(rezeros++)];
        set_joints(g92.q, q_next_);
        g92.which = JointBits(1) << j;
        g92.e.reset();
    }
    return rezeros;
}

MovePlan& Planner::plan(const ToolMove& mv, LineRun& run) {
    const PlannerState& s = state_;
    MovePlan& p = plan_;
    Pose next;
    IkResult r = solve_end(mv, next);
    const bool tool_space = mv.any_xyz || s.tip_known;
    p.prints = extrudes(mv.e, mv.e_relative, mv.e_position);
    p.travel = tool_space && !p.prints && (mv.any_xyz || mv.any_rotary || mv.any_ijk);
    run.travels = run.travels || p.travel;
    p.change = SolutionChange::None;
    p.unwind = other_end(mv, next, p.travel, r, run, p.change);
    if (!r.ok()) {
        run.hit_limit = r.status == IkStatus::OutOfLimits;
        run.linear_limit = run.hit_limit && r.linear;
        run.absent_limit = run.hit_limit && r.absent;
        throw LineError(mv.column, r.message);
    }
    // Near a pole the end may be chosen across moves (pole_policy.hpp): rotaries turn linearly.
    p.passage = false;
    p.passage_angle = 0;
    bool start_held = false;
    if (!p.unwind && mv.mode == OrientationMode::Vector && (mv.any_xyz || s.tip_known) &&
        pole_hold_.passage(s.q, q_next_, s.pose, next, mv.any_ijk ? &end_solutions_ : nullptr, pole_q_, p.passage_angle,
                           log_ != nullptr, start_held, run.pole)) {
        p.passage = true;
        q_next_ = pole_q_;
    }
    PlannedMove& spec = p.move;
    plan_move(mv, s, next, q_next_, end_solutions_, spec);
    // An unwinding travel move turns the rotaries linearly from their start to the chosen end
    // (angle form) while the split holds the tip on the straight travel line, rather than
    // reorienting in place at one end: the tip never leaves the path the slicer planned for it
    // (usually lifted clear of the part), no end of a printed bead gets a hot nozzle sweeping
    // round on it, and each rotary moves monotonically between two values inside its limits.
    // For a branch flip (rw2: A by 180 degrees, B to -B) the tool passes upright (B = 0) on the
    // way instead of sweeping a full turn at its printing tilt.
    if (p.unwind || p.passage) spec.mode = OrientationMode::Angles;
    if (p.passage && pole_hold_.turn().valid) spec.turn = pole_hold_.turn();
    spec.start_held = start_held && !p.passage;
    p.column = mv.column;
    p.places_tip = mv.any_xyz;
    p.measure = log_ && spec.mode != OrientationMode::Joints;
    return p;
}

void Planner::refused(const MovePlan& p, const IkResult& res, LineRun& run) {
    run.hit_limit = res.status == IkStatus::OutOfLimits;
    run.linear_limit = run.hit_limit && res.linear;
    run.absent_limit = run.hit_limit && res.absent;
    run.at_pole = res.status == IkStatus::Singular;
    throw LineError(p.column, res.message);
}

std::span<const SetJoints> Planner::arrived(const MovePlan& p, MoveResult* measured, LineRun& run) {
    if (measured) {
        measured->prints = p.prints;
        if (double bound = 0; bound_rotary_travel(kin_, pole_hold_.pole(), state_, p.move.p1.axis, bound)) log_->set_rotary_bound(bound);
        measured->change = p.change;
        if (p.passage) {
            // The split measures the tip only in angle form: the axis as checked above.
            measured->angle_error = std::max(measured->angle_error, p.passage_angle);
            const std::size_t b = std::size_t(kin_.rotary_joints()[1]);
            if (state_.q[b] * q_next_[b] < 0) measured->pole_crossings = 1;  // the tilt changed sign: the other branch
        }
    }
    // Under absolute E, E0 after E5 extrudes (backwards): only an unchanged E does not.
    const int rezeros = p.prints ? 0 : rezero();
    // The move's events are logged whole, with its re-zeros (translator.cpp logs those of a
    // move not measured, once written).
    if (measured) {
        measured->rezeros = rezeros;
        log_->add(run.line_no, *measured);
    }
    move_on(p);
    return {rezeros_.data(), std::size_t(rezeros)};
}

JointStep Planner::joint_move(const cmd::JointMove& mv) {
    std::vector<double>& q = q_next_;
    q = state_.q;
    for (cmd::JointBits b = mv.given; b != 0; b &= b - 1) {
        const std::size_t j = std::size_t(std::countr_zero(b));
        q[j] = mv.relative ? state_.q[j] + mv.q[j] : mv.q[j];
    }
    if (auto r = check_limits(kin_.machine(), q); !r.ok()) throw LineError(mv.column, r.message);
    state_.q.assign(q.begin(), q.end());
    state_.pose = kin_.forward(state_.q);
    state_.tip_known = state_.tip_known || mv.any_linear;
    JointStep step;
    step.gcode = mv.gcode;
    set_joints(step.q, state_.q);
    step.given = mv.given;
    step.e = mv.e;
    step.f = mv.f;
    step.inverse_time = mv.inverse_time;  // under G93 every move keeps its F
    return step;
}

SetJoints Planner::set_position(const cmd::SetPosition& set) {
    for (cmd::JointBits b = set.which; b != 0; b &= b - 1) {
        const std::size_t j = std::size_t(std::countr_zero(b));
        state_.q[j] = set.q[j];
    }
    // The program and the firmware now agree on the joints named.
    angle_map_.forget_rezeros(state_, set.which);
    if (set.which) angle_map_.plain(state_);
    // The machine did not move: its true pose follows from the joints it now says it is at.
    if (set.pose_from_joints) state_.pose = kin_.forward(state_.q);
    // G92 X Y Z: the program frame moves so that the tip is there; the program has placed it.
    for (std::size_t i = 0; i < 3; ++i) {
        if (!(set.xyz_given & (1u << i))) continue;
        state_.offset[Eigen::Index(i)] = state_.pose.tip[Eigen::Index(i)] - set.xyz[i];
        state_.tip_known = true;
    }
    if (set.e) state_.e = set.e->value;
    SetJoints told;
    set_joints(told.q, state_.q);
    told.which = set.which;
    told.e = set.e;
    return told;
}

void Planner::home(const cmd::Home& home) {
    for (std::size_t j = 0; j < state_.q.size(); ++j)
        if (home.which & (1u << j)) state_.q[j] = kin_.machine().joints[j].home;
    angle_map_.forget_rezeros(state_, home.which);
    angle_map_.plain(state_);
    state_.tip_known = false;
    state_.pose = kin_.forward(state_.q);
    state_.offset.setZero();
}

void Planner::moved_to(const cmd::MovedTo& to) {
    q_next_ = state_.q;
    for (cmd::JointBits b = to.given; b != 0; b &= b - 1) {
        const std::size_t j = std::size_t(std::countr_zero(b));
        q_next_[j] = to.q[j];
    }
    moved_to(q_next_);
}

void Planner::moved_to(const std::vector<double>& q) {
    state_.q.assign(q.begin(), q.end());
    state_.pose = kin_.forward(state_.q);
}


}  // namespace xlate5
