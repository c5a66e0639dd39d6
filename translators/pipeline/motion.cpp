// SPDX-License-Identifier: GPL-3.0-or-later
// The motion stage: split, E and F of one solved move. What it may call: see motion.hpp.
#include "translators/pipeline/motion.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <span>

#include "translators/constants.hpp"
#include "translators/error.hpp"
#include "translators/kinematics/great_arc.hpp"
#include "translators/pipeline/joint_limits.hpp"
#include "translators/number.hpp"

namespace xlate5 {

MotionStage::MotionStage(const Kinematics& kinematics, JointEmitter& emitter)
    : kin_(kinematics),
      machine_(kinematics.machine()),
      joints_(kinematics.machine().joints.size()),
      segment_(kinematics),
      feed_rule_(kinematics.machine()),
      compensation_(kinematics.machine().compensation),
      emitter_(emitter) {}

MotionOutcome MotionStage::emit(const PlannedMove& mv, std::string& out, MoveResult* result) {
    if (mv.end_solutions) segment_.points().remember_solutions(*mv.end_solutions);
    crossed_ = false;
    if (result) result->pole_crossings = 0;  // set by the move that crosses, not kept from an earlier one
    MotionOutcome outcome{emit_move(mv, out, result)};
    // The last part's split ends the move: where a tool vector's continuous solution arrived, or
    // the other branch a crossing took. A move written whole otherwise ends on its own q1.
    if (outcome.ok() && mv.mode == OrientationMode::Vector && (crossed_ || !segment_.pieces().whole())) {
        const double* end = segment_.pieces().end_exact();
        std::copy(end, end + joints_, outcome.ended.emplace().begin());
    }
    return outcome;
}

// Leaving a pole (pole_policy.hpp: re-index): at the start the tool axis is on a rotary axis, so
// that joint was free and kept its old angle, but the path leaves in a direction that needs
// another angle. Turn it first, with the tip and the tool axis held (a re-index about the pole),
// then make the move; never a jump inside one joint move. True when the move was written that
// way, or failed (`r` says which). Vector moves, when the machine splits.
bool MotionStage::leave_pole(const PlannedMove& mv, std::string& out, MoveResult* result, IkResult& r) {
    std::vector<double>& q_eps = probe_q_;
    // The probe's IK only where it matters: at a pole, on a move that turns.
    const double probe = pole_leaving_probe(segment_.points().solutions_of(mv.p0.axis), kin_.rotary_joints().size(), mv.p0.axis, mv.p1.axis);
    if (!(probe > 0)) return false;
    const std::vector<double>& q0 = start_of(mv);
    if (!segment_.points().solve_at(mv, probe, q0, q_eps).ok()) return false;
    std::vector<double> turned;
    if (r = pole_reindex(kin_, q0, q_eps, mv.p0.tip, turned); !r.ok()) return true;
    if (turned.empty()) return false;
    PlannedMove turn = mv;
    turn.mode = OrientationMode::Angles;
    set_joints(turn.q1, turned);
    turn.p1 = mv.p0;
    turn.p1.axis = kin_.forward(turned).axis;
    turn.e.reset();
    turn.f.reset();
    turn.inverse_time = 0;
    std::string text;
    MoveResult first;
    if (r = emit_one(turn, text, &first); !r.ok()) return true;
    PlannedMove rest = mv;
    set_joints(rest.q0, turned);
    if (r = emit_one(rest, text, result); !r.ok()) return true;
    out += text;
    if (result) {
        result->pieces += first.pieces;
        result->tip_error = std::max(result->tip_error, first.tip_error);
        result->angle_error = std::max(result->angle_error, first.angle_error);
        // The turn about the pole is rotary travel of this move too.
        result->travel.resize(first.travel.size(), 0.0);
        for (std::size_t j = 0; j < first.travel.size(); ++j) result->travel[j] += first.travel[j];
        result->minutes += first.minutes;
        for (std::size_t j = 0; j < result->low.size() && j < first.low.size(); ++j) {
            result->low[j] = std::min(result->low[j], first.low[j]);
            result->high[j] = std::max(result->high[j], first.high[j]);
        }
    }
    r = {};
    return true;
}

inline IkResult MotionStage::emit_move(const PlannedMove& mv, std::string& out, MoveResult* result) {
    split_for_ = nullptr;
    if (mv.turn.valid) return turn_in_place(mv, out, result);
    if (mv.mode == OrientationMode::Vector && machine_.motion.segment) {
        if (IkResult r; leave_pole(mv, out, result, r)) return r;
    }
    // Only a vector move can cross (cross_pole's own first test, made here without the call).
    if (mv.mode == OrientationMode::Vector && cross_pole(mv, cross_end_)) {
        // Across the pole (Isa, Koc 2018, sec. 4.6: C patched linearly through the singular
        // cone): the rotaries turn linearly to the other branch while the split holds the tip
        // on the line; the tool axis stays within the angle tolerance (checked in cross_pole).
        PlannedMove across = mv;
        across.mode = OrientationMode::Angles;
        set_joints(across.q1, cross_end_);
        if (auto r = emit_one(across, out, result); !r.ok()) return r;
        crossed_ = true;
        if (result) {
            result->pole_crossings = 1;
            result->angle_error = std::max(result->angle_error, cross_angle_);
        }
        return {};
    }
    if (mv.start_held && mv.mode == OrientationMode::Vector) {
        // From a start the planner held off its axis: the continuous solution is tried first (the
        // split is kept), and only where it cannot be followed is the move joined onto it.
        if (split_for_ != &mv) {
            if (auto r = segment_.split(mv); !r.ok()) {
                std::string joined;
                MoveResult whole;
                if (join_from_held(mv, joined, result ? &whole : nullptr).ok()) {
                    out += joined;
                    if (result) *result = whole;
                    return {};
                }
                return r;
            }
            split_for_ = &mv;
        }
    }
    return emit_one(mv, out, result);
}

namespace {
// A move written as two parts, `first` up to s1 and `rest`: E shared by tip length as emit_one
// shares it among pieces, the first part's at the dialect's decimals, the rest what is left (the
// parts add up to the input exactly).
void share_e(const PlannedMove& mv, double s1, int ed, PlannedMove& first, PlannedMove& rest) {
    if (!mv.e) return;
    const double escale = std::pow(10.0, ed);
    const double value = mv.e_relative ? mv.e->value : mv.e->value - mv.e_start;
    const long long units = std::llround(value * s1 * escale);
    if (mv.e_relative) {
        first.e = PassedNumber{double(units) / escale, {}, ed};
        const double total = value * escale;
        if (std::abs(total - std::round(total)) < 1e-6)
            rest.e = PassedNumber{double(std::llround(total) - units) / escale, {}, ed};
        else
            rest.e = PassedNumber{value - double(units) / escale, {}};
    } else {
        first.e = PassedNumber{double(units) / escale + mv.e_start, {}, ed};
        rest.e_start = first.e->value;
    }
}

// A second part's figures added to the first's (a move written as two).
void add_result(MoveResult& into, const MoveResult& part) {
    into.pieces += part.pieces;
    into.tip_error = std::max(into.tip_error, part.tip_error);
    into.angle_error = std::max(into.angle_error, part.angle_error);
    if (std::abs(part.feed_error) > std::abs(into.feed_error)) into.feed_error = part.feed_error;
    into.travel.resize(std::max(into.travel.size(), part.travel.size()), 0.0);
    for (std::size_t j = 0; j < part.travel.size(); ++j) into.travel[j] += part.travel[j];
    into.minutes += part.minutes;
    into.pole_crossings += part.pole_crossings;
    if (into.low.empty()) {
        into.low = part.low;
        into.high = part.high;
    }
    for (std::size_t j = 0; j < into.low.size() && j < part.low.size(); ++j) {
        into.low[j] = std::min(into.low[j], part.low[j]);
        into.high[j] = std::max(into.high[j], part.high[j]);
    }
}
}  // namespace

IkResult MotionStage::join_from_held(const PlannedMove& mv, std::string& out, MoveResult* result) {
    double worst = 0;
    const double s1 = pole_join(kin_, start_of(mv), mv.p0.tip, mv.p1.tip, segment_.points().arc_of(mv), cross_scratch_, join_q_, worst);
    if (s1 == 0) return {IkStatus::Singular, "no join"};
    const Pose mid = segment_.points().pose_at(mv, s1);
    PlannedMove first = mv, rest = mv;
    first.mode = OrientationMode::Angles;
    first.start_held = false;
    set_joints(first.q1, join_q_);
    first.p1 = mid;
    first.end.valid = false;
    rest.start_held = false;
    rest.q0 = first.q1;
    rest.p0 = mid;
    if (mv.inverse_time > 0) {
        first.inverse_time = mv.inverse_time / s1;
        rest.inverse_time = mv.inverse_time / (1 - s1);
    }
    share_e(mv, s1, machine_.dialect.extrusion_decimals, first, rest);
    MoveResult a, b;
    if (auto r = emit_one(first, out, result ? &a : nullptr); !r.ok()) return r;
    if (auto r = emit_move(rest, out, result ? &b : nullptr); !r.ok()) return r;
    if (result) {
        a.angle_error = std::max(a.angle_error, worst);  // the angle form measures the tip: the axis as checked above
        add_result(a, b);
        *result = a;
    }
    return {};
}

IkResult MotionStage::turn_in_place(const PlannedMove& mv, std::string& out, MoveResult* result) {
    const PoleTurn& turn = mv.turn;
    const double s1 = turn.at;
    const Pose mid{mv.p0.tip + s1 * (mv.p1.tip - mv.p0.tip), kin_.tool_axis(turn.before)};
    PlannedMove first = mv, in_place = mv, rest = mv;
    first.turn.valid = in_place.turn.valid = rest.turn.valid = false;
    set_joints(first.q1, turn.before);
    first.p1 = mid;
    first.end.valid = false;
    in_place.q0 = first.q1;
    in_place.p0 = mid;
    set_joints(in_place.q1, turn.after);
    in_place.p1 = mid;
    in_place.p1.axis = kin_.tool_axis(turn.after);
    in_place.end.valid = false;
    in_place.e.reset();
    in_place.f.reset();
    in_place.inverse_time = 0;
    rest.q0 = in_place.q1;
    rest.p0 = in_place.p1;
    if (mv.inverse_time > 0) {
        first.inverse_time = mv.inverse_time / s1;
        rest.inverse_time = mv.inverse_time / (1 - s1);
    }
    share_e(mv, s1, machine_.dialect.extrusion_decimals, first, rest);
    // Written into a buffer: a part that cannot be split leaves nothing behind.
    std::string text;
    MoveResult a, t, b;
    if (auto r = emit_one(first, text, result ? &a : nullptr); !r.ok()) return r;
    if (auto r = emit_one(in_place, text, result ? &t : nullptr); !r.ok()) return r;
    if (auto r = emit_one(rest, text, result ? &b : nullptr); !r.ok()) return r;
    out += text;
    if (result) {
        add_result(a, t);
        add_result(a, b);
        *result = a;
    }
    return {};
}

bool MotionStage::cross_pole(const PlannedMove& mv, std::vector<double>& end) {
    if (mv.mode != OrientationMode::Vector || !machine_.motion.segment || kin_.rotary_joints().size() != 2) return false;
    // The continuous branch's split is made first: the way across is taken only when it turns
    // the rotaries clearly less than that split, and when it is not taken the split is kept for
    // emit_one, not made again.
    const bool split_ok = segment_.split(mv).ok();
    const double measured = split_ok ? segment_.split_rotary_travel() : 0.0;
    // No end on another branch can be clearly nearer than a split that turns the rotaries less
    // than the margin (most moves, far from a pole): no estimate then.
    if (split_ok && measured <= kPoleClearlyLess) {
        split_for_ = &mv;
        return false;
    }
    const bool across = pole_crossing(kin_, start_of(mv), mv.p1.tip, segment_.points().arc_of(mv), segment_.points().solutions_of(mv.p1.axis), split_ok, measured,
                                      cross_scratch_, end, cross_angle_);
    if (split_ok && !across) split_for_ = &mv;
    return across;
}

namespace {

// E shared among a move's pieces by tip length: each piece's E at the dialect's decimals, the
// last one's exactly what the input said (absolute E as written; relative E as what is left), so
// the pieces add up to the input exactly.
class EShare {
public:
    EShare(const PlannedMove& mv, int decimals) : mv_(mv), ed_(decimals) {
        // 10^ed from a table for the usual decimals (the same exact value pow gives, without the call).
        static constexpr double kPow10[] = {1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9};
        escale_ = ed_ >= 0 && ed_ <= 9 ? kPow10[ed_] : std::pow(10.0, ed_);
    }
    // The E of the piece ending at `share` of the move.
    std::optional<PassedNumber> piece(double share, bool last, int pieces) {
        const PlannedMove& mv = mv_;
        if (!mv.e) return std::nullopt;
        if (last) {
            if (!mv.e_relative || pieces == 1) return mv.e;
            const double total = mv.e->value * escale_;
            if (std::abs(total - std::round(total)) < 1e-6)  // E has no more digits than the pieces
                return PassedNumber{double(std::llround(total) - units_done_) / escale_, {}, ed_};
            // The rest to the programmed E's own decimals, so the pieces' words add up to it
            // (unrounded, 0.000964506164 less 0.00048 was written 0.00048450616399999994).
            const int given = plain_decimals(mv.e->text);
            return PassedNumber{mv.e->value - double(units_done_) / escale_, {}, given < 0 ? -1 : std::max(given, ed_)};
        }
        const double value = mv.e_relative ? mv.e->value : mv.e->value - mv.e_start;
        const long long upto = std::llround(value * share * escale_);
        const long long units = mv.e_relative ? upto - units_done_ : upto;
        units_done_ = mv.e_relative ? upto : 0;
        return PassedNumber{double(units) / escale_ + (mv.e_relative ? 0.0 : mv.e_start), {}, ed_};
    }

private:
    const PlannedMove& mv_;
    int ed_;
    double escale_;
    long long units_done_ = 0;
};

// The feed terms of a move: its duration at the programmed feed (G94) or as given (G93), and
// whether the firmware is given inverse-time feeds (where it takes them, for tool-space moves
// that have a duration).
MoveFeed move_feed(const PlannedMove& mv, const Machine& machine) {
    MoveFeed feed;
    feed.length = (mv.p1.tip - mv.p0.tip).norm();
    if (mv.inverse_time > 0) feed.minutes = 1.0 / mv.inverse_time;
    else if (mv.feed > 0 && mv.mode != OrientationMode::Joints) feed.minutes = feed.length / mv.feed;
    feed.feed = mv.feed;
    feed.inverse_time = mv.inverse_time;
    feed.f = mv.f;
    if (mv.e) feed.e = std::abs(mv.e_relative ? mv.e->value : mv.e->value - mv.e_start);
    feed.inverse_time_out = machine.dialect.inverse_time && mv.mode != OrientationMode::Joints && (feed.minutes > 0 || mv.feed > 0);
    return feed;
}

}  // namespace

IkResult MotionStage::emit_one(const PlannedMove& mv, std::string& out, MoveResult* result) {
    if (split_for_ != &mv)
        if (auto r = segment_.split(mv); !r.ok()) return r;
    split_for_ = nullptr;
    const std::size_t n = joints_;
    const int pieces = int(segment_.pieces().count());
    const std::vector<double>& params = segment_.pieces().params();
    const MoveFeed feed = move_feed(mv, machine_);
    EShare e_share(mv, machine_.dialect.extrusion_decimals);
    piece_time_.resize(std::size_t(pieces));  // each piece's set below
    // Each piece's ends are read where the split left them (no copies), from where the firmware starts.
    std::span<const double> qprev(segment_.pieces().start_printed());
    double prev_share = 0;
    for (int k = 0; k < pieces; ++k) {
        // The tip moves uniformly in s along the straight programmed line: s is the piece's share.
        const double share = params[std::size_t(k)];
        const std::span<const double> qk(segment_.pieces().printed(std::size_t(k)), n);
        const std::optional<PassedNumber> e = e_share.piece(share, k + 1 == pieces, pieces);
        std::optional<PassedNumber> f;
        if (mv.mode == OrientationMode::Joints) {
            f = mv.f;  // joint space: the firmware's own F, as given
            piece_time_[std::size_t(k)] = 0;   // not known
        } else {
            const PieceFeed pf = feed_rule_.piece(feed, qprev, qk, share - prev_share);
            piece_time_[std::size_t(k)] = pf.minutes;
            f = pf.f;
        }
        // Measured errors are taken off after the split, so every piece of every move is
        // corrected and nothing upstream sees anything but nominal joints.
        // Compensated from the joints as solved: the emitter rounds once (without compensation
        // that gives exactly the rounded joints checked above).
        const double* exact = segment_.pieces().exact(std::size_t(k));
        const auto sent = compensation_.apply(std::span<const double>(exact, n));
        if (!sent.ok()) throw LineError(1, sent.why());
        emitter_.move(out, mv.gcode, qk, sent.sent, mv.commanded, e, f, feed.inverse_time_out);
        prev_share = share;
        qprev = qk;
    }
    if (result) measure(mv, *result);
    return {};
}

void MotionStage::measure(const PlannedMove& mv, MoveResult& result) const {
    // The report: deviation of each piece (denser than the split's own check), the tip's real
    // speed along the firmware's path against the programmed feed, and joint travel.
    const std::size_t n = joints_;
    const int pieces = int(segment_.pieces().count());
    const std::vector<double>& params = segment_.pieces().params();
    const std::vector<double>& q0 = segment_.pieces().start_printed();
    const double length = (mv.p1.tip - mv.p0.tip).norm();
    result.pieces = pieces;
    result.travel.assign(n, 0.0);
    result.low = q0;
    result.high = q0;
    result.minutes = 0;
    double tip = 0, ang = 0, ptip, pang, sa = 0, worst_feed = 0;
    const double* qa = q0.data();
    std::vector<double> qq(n);
    for (int k = 0; k < pieces; ++k) {
        const double* qb = segment_.pieces().printed(std::size_t(k));
        segment_.check().piece_error(mv, sa, params[std::size_t(k)], qa, qb, 2 * Segmenter::kCheckSamples, ptip, pang);
        tip = std::max(tip, ptip);
        ang = std::max(ang, pang);
        for (std::size_t j = 0; j < n; ++j) {
            result.travel[j] += std::abs(qb[j] - qa[j]);
            result.low[j] = std::min(result.low[j], qb[j]);  // joint-linear pieces: extremes at their ends
            result.high[j] = std::max(result.high[j], qb[j]);
        }
        result.minutes += piece_time_[std::size_t(k)];
        if (mv.feed > 0 && mv.mode != OrientationMode::Joints && length > 0) {
            // Tip path length of the joint-linear piece, and the time the firmware gives it.
            double walked = 0;
            Eigen::Vector3d last = kin_.forward(std::vector<double>(qa, qa + n)).tip;
            for (int i = 1; i <= 16; ++i) {
                for (std::size_t j = 0; j < n; ++j) qq[j] = qa[j] + (qb[j] - qa[j]) * i / 16.0;
                const Eigen::Vector3d p = kin_.forward(qq).tip;
                walked += (p - last).norm();
                last = p;
            }
            const double programmed = length * (params[std::size_t(k)] - sa);
            const double minutes = piece_time_[std::size_t(k)];  // as the emitted F gives it
            if (programmed > 1e-9 && minutes > 0) {
                const double err = (walked / minutes) / mv.feed - 1.0;
                if (std::abs(err) > std::abs(worst_feed)) worst_feed = err;
            }
        }
        sa = params[std::size_t(k)];
        qa = qb;
    }
    result.tip_error = tip;
    result.angle_error = ang;
    result.feed_error = worst_feed;
}

}  // namespace xlate5
