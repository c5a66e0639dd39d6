// SPDX-License-Identifier: GPL-3.0-or-later
// The split to tolerance. What it may call: see split.hpp.
#include "translators/pipeline/split.hpp"

#include <algorithm>
#include <cmath>

#include "translators/constants.hpp"
#include "translators/number.hpp"
#include "translators/pipeline/emitter.hpp"

namespace xlate5 {

namespace {

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
// The same of the machine's joints in `from`, written to `to` (no copy first).
void round_printed(const Machine& m, const Joints& from, std::vector<double>& to) {
    to.resize(m.joints.size());
    for (std::size_t j = 0; j < to.size(); ++j) to[j] = printed_value(m, j, from[j]);
}
// A joint vector holds the first joints of an array.
bool same_joints(const std::vector<double>& a, const Joints& b, std::size_t n) {
    return a.size() == n && std::equal(a.begin(), a.end(), b.begin());
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

Segmenter::Segmenter(const Kinematics& kinematics)
    : kin_(kinematics),
      machine_(kinematics.machine()),
      joints_(kinematics.machine().joints.size()),
      points_(kinematics),
      check_(kinematics, points_, kSampleMargin * kinematics.machine().motion.angle_tolerance),
      rounding_(kinematics),
      pieces_(kinematics.machine().joints.size()) {}

IkResult Segmenter::split(const PlannedMove& mv) {
    // A move usually starts where the one before ended: its start as printed is known then.
    // And every move ends exactly on its programmed tip (the planner solves the linear joints
    // for it): a move that starts at the last one's end, joints and tip, starts on its line.
    std::vector<double>& last_end_q = pieces_.q1_exact_;
    const std::size_t n = joints_;
    const bool from_last = same_joints(last_end_q, mv.q0, n);
    const bool start_on_line = from_last && mv.p0.tip == last_end_tip_;
    // q1 (the pieces' end as printed) holds the last move's end as printed (last_end_q
    // rounded): taken, then refilled. The ends' slots (path_end) follow: the last end's is the
    // start's now.
    std::vector<double>& q0 = pieces_.q0_printed_;
    std::vector<double>& q1 = pieces_.q1_printed_;
    if (from_last) q0.swap(q1);
    else round_printed(machine_, mv.q0, q0);
    check_.next_move(from_last);
    bool rotates = false;
    if (n <= kMaxJoints && q0.size() == n && q1.size() == n && last_end_q.size() == n) {
        // The usual move (every one after the first): one pass, no copies or calls.
        rotates = rounding_.round_end(mv.q1.data(), q1.data(), last_end_q.data(), q0.data());
    } else {
        round_printed(machine_, mv.q1, q1);
        last_end_q.assign(mv.q1.begin(), mv.q1.begin() + std::ptrdiff_t(n));
        for (const int j : kin_.rotary_joints()) rotates = rotates || q1[std::size_t(j)] != q0[std::size_t(j)];
    }
    last_end_tip_ = mv.p1.tip;
    // One piece, the whole move: read from q1 and the move's own end (no copies).
    if (pieces_.s_.size() == 1) pieces_.s_[0] = 1.0;
    else pieces_.s_.assign(1, 1.0);
    pieces_.whole_ = true;
    // With the rotaries still the tip is affine in the linear joints: the firmware's line is exact.
    if (!rotates || mv.mode == OrientationMode::Joints || !machine_.motion.segment) return {};
    check_.set_ends(q0.data(), q1.data(), mv.end.valid && same_joints(mv.end.q, mv.q1, n) ? &mv.end : nullptr);

    const double tol = kSampleMargin * machine_.motion.tolerance;
    if (start_on_line && check_.reach_clears(mv, tol)) return {};
    if (check_.bounded_within(mv, 0, 1, q0.data(), q1.data(), tol)) return {};
    return march(mv, tol);
}

// Near a pole the continuous branch swings a joint round; the other branch may cut across within
// the tolerance (a tilt through zero instead of a half turn): true, with qb and m_.exact_b that
// branch's end, when one passes.
bool Segmenter::other_branch_passes(const PlannedMove& mv, double sa, double sb, const std::vector<double>& qa,
                                    std::vector<double>& qb, double tol) {
    std::vector<double>& alt = m_.b;
    for (int b = 0; b < 2; ++b) {
        // solve_at(mv, sb, qa, alt, b), on the try's own target. A branch whose rotaries are the
        // continuous solve's to the bit is the branch it took: the position solve would give
        // m_.exact_b again, qb once rounded, which the test below skips; it is skipped here, before
        // that solve.
        ChosenSolution chosen;
        if (!points_.orient_at(mv, sb, m_.target, qa, alt, b, chosen).ok()) continue;
        if (points_.same_rotaries(alt, m_.exact_b)) continue;
        if (!points_.place(m_.target, alt, chosen).ok()) continue;
        std::vector<double>& alt_exact = m_.alt_exact;  // a member: no allocation per try
        alt_exact = alt;
        round_printed(machine_, alt);
        if (alt == qb) continue;
        if (check_.bounded_within(mv, sa, sb, qa.data(), alt.data(), tol) || check_.piece_within(mv, sa, sb, qa.data(), alt.data(), tol)) {
            qb = alt;
            m_.exact_b = alt_exact;
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
// swing the tip really makes): true, with qb and m_.exact_b that end, when its piece passes.
bool Segmenter::polar_continuous_passes(const PlannedMove& mv, double sa, double sb, const std::vector<double>& qa,
                                        std::vector<double>& qb, double tol) {
    bool jumped = false;
    for (const int j : kin_.rotary_joints()) jumped = jumped || std::abs(m_.exact_b[std::size_t(j)] - qa[std::size_t(j)]) > 60.0;
    if (!jumped) return false;
    std::vector<double>& alt = m_.b;
    alt = qa;
    ChosenSolution chosen;
    if (!orient_within_limits(machine_, kin_.rotary_joints(), m_.target.solutions, qa, qa, alt, &chosen).ok()) return false;
    if (!points_.place(m_.target, alt, chosen).ok()) return false;
    std::vector<double>& alt_exact = m_.alt_exact;
    alt_exact = alt;
    round_printed(machine_, alt);
    if (!check_.bounded_within(mv, sa, sb, qa.data(), alt.data(), tol) && !check_.piece_within(mv, sa, sb, qa.data(), alt.data(), tol)) return false;
    qb = alt;
    m_.exact_b = alt_exact;
    return true;
}

// The longest piece from sa (joints qa = m_.march_a, as printed) that passes: halved until one
// passes, then closed in on the limit between the longest passing and the shortest failing
// length. Its length in ok_len, its end in m_.a (as printed) and m_.ok_exact (as solved).
IkResult Segmenter::longest_piece(const PlannedMove& mv, double tol, double sa, double step, double& ok_len) {
    const auto& q1 = pieces_.q1_printed_;
    const std::vector<double>& qa = m_.march_a;
    std::vector<double>& qb = m_.march_b;
    double bad_len = 0;
    ok_len = 0;
    std::vector<double>& qok = m_.a;
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
            points_.target_at(mv, std::min(sb, 1.0), m_.target);
            ChosenSolution chosen;
            r = points_.orient_at(mv, std::min(sb, 1.0), m_.target, qa, qb, -1, chosen);
            if (r.ok()) r = points_.place(m_.target, qb, chosen);
        } else {
            r = points_.solve_at(mv, std::min(sb, 1.0), qa, qb);
        }
        if (!r.ok()) {
            r.message += " (at " + std::to_string(int(std::lround(std::min(sb, 1.0) * 100))) + "% of the move)";
            return r;
        }
        if (sb >= 1.0 && mv.mode == OrientationMode::Angles) m_.exact_b.assign(mv.q1.begin(), mv.q1.begin() + std::ptrdiff_t(joints_));
        else m_.exact_b = qb;
        round_printed(machine_, qb);
        double middle_ratio = 0;  // the failing middle sample's error over the tolerance (0: not known)
        bool pass = check_.bounded_within(mv, sa, std::min(sb, 1.0), qa.data(), qb.data(), tol);
        if (!pass) pass = check_.piece_within(mv, sa, std::min(sb, 1.0), qa.data(), qb.data(), tol, &middle_ratio);
        if (!pass && mv.mode == OrientationMode::Vector) pass = other_branch_passes(mv, sa, std::min(sb, 1.0), qa, qb, tol);
        if (!pass && mv.mode == OrientationMode::Vector && kin_.is_polar()) pass = polar_continuous_passes(mv, sa, std::min(sb, 1.0), qa, qb, tol);
        if (pass) {
            ok_len = len;
            qok = qb;
            m_.ok_exact = m_.exact_b;
        } else {
            bad_len = len;
            if (len < 1e-9) {
                // Either a pole, or the continuous solution runs out of a joint's limits here
                // and the nearest one inside them is on another branch or turn: say which.
                if (auto rl = points_.leaves_limits(mv, std::min(sb, 1.0), qa); !rl.ok()) return rl;
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

IkResult Segmenter::march(const PlannedMove& mv, double tol) {
    const auto& q0 = pieces_.q0_printed_;
    const auto& q1 = pieces_.q1_printed_;
    const double atol = check_.angle_limit();
    double tip = 0, ang = 0;
    check_.piece_error(mv, 0, 1, q0.data(), q1.data(), kCheckSamples, tip, ang);
    const double ratio = std::max(tip / tol, ang / atol);
    if (ratio <= 1) return {};

    // March along the move from s = 0, each piece as long as the tolerance allows (greedy
    // farthest reach, which gives the fewest pieces when the error grows with piece length), each
    // point solved from the one before so the solution stays on one continuous branch. The
    // chord error of a smooth path falls with the square of the piece length, which gives the
    // first guess of the step.
    pieces_.s_.clear();
    pieces_.qs_.clear();
    pieces_.qs_exact_.clear();
    pieces_.whole_ = false;
    double step = 1.0 / std::ceil(std::sqrt(ratio));
    double sa = 0;
    std::vector<double>& qa = m_.march_a;
    std::vector<double>& qb = m_.march_b;
    qa = q0;
    while (sa < 1.0) {
        double ok_len = 0;
        if (auto r = longest_piece(mv, tol, sa, step, ok_len); !r.ok()) return r;
        const std::vector<double>& qok = m_.a;
        const double sb = std::min(1.0, sa + ok_len);
        qb = qok;
        step = std::max(sb - sa, 1e-9) * 1.25;  // the next piece is likely about as long: start a bit farther
        pieces_.s_.push_back(sb);
        pieces_.qs_.insert(pieces_.qs_.end(), qb.begin(), qb.end());
        pieces_.qs_exact_.insert(pieces_.qs_exact_.end(), m_.ok_exact.begin(), m_.ok_exact.end());
        const int bound = pieces_bound(machine_.motion.max_pieces);
        if (int(pieces_.s_.size()) > bound)  // refused, not silently truncated (docs/limits.md)
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
    const double* qa = pieces_.q0_printed_.data();
    for (std::size_t k = 0; k < pieces_.s_.size(); ++k) {
        const double* qb = pieces_.printed(k);
        for (const int j : rot) travel += std::abs(qb[std::size_t(j)] - qa[std::size_t(j)]);
        qa = qb;
    }
    return travel;
}

}  // namespace xlate5
