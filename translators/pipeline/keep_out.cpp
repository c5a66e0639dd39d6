// SPDX-License-Identifier: GPL-3.0-or-later
// The keep-out stage: R from the path and the keep-out items (ADD_IN team, 2015).
// What it may call: see keep_out.hpp.
#include "translators/pipeline/keep_out.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <sstream>

#include "translators/constants.hpp"
#include "translators/error.hpp"
#include "translators/inputs/gcode_lexer.hpp"
#include "translators/inputs/small_file.hpp"

namespace xlate5 {

namespace {

// An item nearer than this to the line of a move lies on it (the source's side = 0).
constexpr double kOnLine = 1e-6;  // mm
// Moves shorter than this in X/Y have no direction: R stays.
constexpr double kNoDirection = 1e-9;  // mm
constexpr double kHeightSlack = 1e-6;  // mm: "at or below the current Z"

double cross(const Eigen::Vector2d& a, const Eigen::Vector2d& b) { return a.x() * b.y() - a.y() * b.x(); }

// A row of three column names before the first item (`x,y,height`, `X; Y; Z (mm)`): each field
// starts with a letter and none reads as a number, so no data row can be taken for one.
bool is_header_row(std::string_view body) {
    auto sep = [](char c) { return c == ',' || c == '\t' || c == ';'; };
    int fields = 0;
    std::size_t i = 0;
    while (i <= body.size()) {
        std::size_t j = i;
        while (j < body.size() && !sep(body[j])) ++j;
        std::string_view f = body.substr(i, j - i);
        while (!f.empty() && (f.front() == ' ' || f.front() == '"')) f.remove_prefix(1);
        while (!f.empty() && (f.back() == ' ' || f.back() == '\r' || f.back() == '"')) f.remove_suffix(1);
        if (f.empty() && j >= body.size() && fields > 0) break;
        const bool letter = !f.empty() && ((f[0] >= 'a' && f[0] <= 'z') || (f[0] >= 'A' && f[0] <= 'Z'));
        if (!letter) return false;
        double x = 0;
        if (const auto [end, ec] = std::from_chars(f.data(), f.data() + f.size(), x); ec == std::errc() && end == f.data() + f.size())
            return false;  // "inf", "nan": numbers, refused where they are read
        for (char c : f)
            if (static_cast<unsigned char>(c) < 0x20) return false;
        ++fields;
        i = j + 1;
    }
    return fields == 3;
}

}  // namespace

KeepOutItems parse_keep_out(const std::string& text, const std::string& name) {
    KeepOutItems r;
    r.file = name;
    std::istringstream in(text);
    std::string line;
    std::uint64_t n = 0;
    bool data_seen = false;
    while (std::getline(in, line)) {
        ++n;
        // A UTF-8 byte-order mark (what Windows editors put first) is no part of the data.
        if (n == 1 && line.rfind("\xEF\xBB\xBF", 0) == 0) line.erase(0, 3);
        const std::string_view body = std::string_view(line).substr(0, line.find('#'));
        if (!data_seen && is_header_row(body)) continue;  // a spreadsheet's "x,y,height"
        double v[3];
        int count = 0;
        std::size_t i = 0;
        auto sep = [](char c) { return c == ' ' || c == '\t' || c == ',' || c == '\r' || c == ';'; };
        while (true) {
            while (i < body.size() && sep(body[i])) ++i;
            if (i >= body.size()) break;
            std::size_t j = i;
            while (j < body.size() && !sep(body[j])) ++j;
            std::string_view t = body.substr(i, j - i);
            if (count == 3) throw InputError(name, n, std::uint32_t(i + 1), "a keep-out item is x, y, height (3 numbers)");
            if (t.front() == '+') t.remove_prefix(1);
            double x = 0;
            const auto [end, ec] = std::from_chars(t.data(), t.data() + t.size(), x);
            if (ec != std::errc() || end != t.data() + t.size() || t.empty())
                throw InputError(name, n, std::uint32_t(i + 1), "'" + std::string(body.substr(i, j - i)) + "' is not a number");
            if (!std::isfinite(x) || std::abs(x) > kMaxNumber) throw InputError(name, n, std::uint32_t(i + 1), "number beyond +-1e9");
            v[count++] = x;
            i = j;
        }
        if (count == 0) continue;
        data_seen = true;
        if (count != 3) throw InputError(name, n, std::uint32_t(body.size() + 1), "a keep-out item is x, y, height (3 numbers)");
        r.items.push_back({Eigen::Vector2d(v[0], v[1]), v[2], n});
    }
    return r;
}

KeepOutItems load_keep_out(const std::string& path) {
    return parse_keep_out(read_small_file(path, kMaxKeepOutBytes, "a keep-out list"), path);
}

KeepOutStage::KeepOutStage(const Kinematics& kinematics, const KeepOutItems& items, const PlannerState& state)
    : kin_(kinematics), items_(items), state_(state), angles_{kinematics.rotary_joints()} {
    const Machine& m = kin_.machine();
    const auto& rot = kin_.rotary_joints();
    bool about_own_axis = rot.size() == 1;
    if (about_own_axis) {
        r_ = rot[0];
        std::vector<double> q = m.home_joints();
        for (const double a : {0.0, 90.0, 200.0}) {
            q[std::size_t(r_)] = a;
            about_own_axis = about_own_axis && kin_.forward(q).axis.z() > 1 - 1e-9;
        }
    }
    if (!about_own_axis)
        throw MachineError(m.name + ": --keep-out needs a machine with one rotary that turns the nozzle about its own "
                                    "vertical axis (such as addin4)");
}

int KeepOutStage::nearest(const Eigen::Vector2d& p, double z) const {
    int best = -1;
    double best_d = 0;
    for (std::size_t k = 0; k < items_.items.size(); ++k) {
        const KeepOutItem& it = items_.items[k];
        if (it.height > z + kHeightSlack) continue;
        const double d = (it.centre - p).squaredNorm();
        if (best < 0 || d < best_d) best = int(k), best_d = d;
    }
    return best;
}

double KeepOutStage::normal_toward(const Eigen::Vector2d& p, const Eigen::Vector2d& d, int k, std::uint32_t column) const {
    const KeepOutItem& it = items_.items[std::size_t(k)];
    // The source's side = det([m, n]) with n = c - p1, m = c - p2 equals cross(n, d); here the
    // sign is taken as cross(d, n), positive when the item lies left of the direction of travel,
    // so that R = alpha + 90 points at it (as the source's figure 2 shows the nozzle doing).
    const double side = cross(d, it.centre - p);
    if (std::abs(side) / d.norm() < kOnLine) {
        std::ostringstream s;
        s << "keep-out item at (" << it.centre.x() << ", " << it.centre.y() << ") (" << items_.file << " line " << it.line
          << ") lies on the line of this move: the nozzle cannot point at it normal to the path";
        throw LineError(column, s.str());
    }
    const double alpha = std::atan2(d.y(), d.x()) * kDegPerRad;
    return side > 0 ? alpha + 90 : alpha - 90;
}

double KeepOutStage::continuous(double from, double r, const Eigen::Vector2d& p, int a, int b, double shift) const {
    const double short_way = from + wrap180(r - from);
    if (std::abs(short_way - from) < 1e-9) return from;
    const double long_way = short_way - std::copysign(360.0, short_way - from);
    // Does the pointing direction pass (strictly) through the one straight away from item k?
    auto passes_away = [&](double to, int k) {
        if (k < 0) return false;
        const Eigen::Vector2d v = p - items_.items[std::size_t(k)].centre;
        if (v.norm() < kOnLine) return false;
        const double away = std::atan2(v.y(), v.x()) * kDegPerRad;
        const double lo = std::min(from, to), hi = std::max(from, to);
        const double first = away + 360.0 * std::ceil((lo - away) / 360.0);
        return first > lo + 1e-9 && first < hi - 1e-9;
    };
    auto clear = [&](double to) { return !passes_away(to, a) && !passes_away(to, b); };
    const bool short_clear = clear(short_way), long_clear = clear(long_way);
    if (short_clear != long_clear) return short_clear ? short_way : long_way;
    // Both clear with one shorter: the shorter. Otherwise (a half turn, or a change between two
    // items on either side of the path, where any way points past one of them for a moment): the
    // way toward the middle of the joint's limits, so that such turns do not wind R up.
    if (short_clear && std::abs(std::abs(short_way - from) - 180) > 1e-6) return short_way;
    const Joint& J = kin_.machine().joints[std::size_t(r_)];
    const double middle = J.bounded() ? 0.5 * (std::max(J.min, -1e9) + std::min(J.max, 1e9)) : 0.0;
    return std::abs(short_way + shift - middle) <= std::abs(long_way + shift - middle) ? short_way : long_way;
}

void KeepOutStage::send(const ToolMove& mv, double r, bool turn) {
    KeepOutMoves::Step& step = moves_.steps.emplace_back(KeepOutMoves::Step{mv, turn});
    ToolMove& m = step.move;
    m.any_rotary = true;
    m.angles[std::size_t(r_)] = r;
    m.commanded |= JointBits(1) << r_;
}

void KeepOutStage::find_pieces(const Eigen::Vector3d& p1, const Eigen::Vector3d& p2) {
    // Pieces: constant eligibility (split where Z reaches an item's height), then constant
    // nearest item (split where the path crosses the bisector toward a nearer one).
    const Eigen::Vector2d d = (p2 - p1).head<2>();
    std::vector<double> cuts{0.0, 1.0};
    const double z1 = p1.z(), z2 = p2.z();
    if (z1 != z2)
        for (const KeepOutItem& it : items_.items) {
            const double t = (it.height - z1) / (z2 - z1);
            if (t > 1e-12 && t < 1 - 1e-12) cuts.push_back(t);
        }
    std::sort(cuts.begin(), cuts.end());
    pieces_.clear();
    const Eigen::Vector2d P = p1.head<2>();
    for (std::size_t c = 0; c + 1 < cuts.size(); ++c) {
        const double ta = cuts[c], tb = cuts[c + 1];
        if (tb - ta < 1e-12) continue;
        const double z = z1 + (z2 - z1) * 0.5 * (ta + tb);
        double t = ta;
        int k = nearest(P + d * (ta + 1e-9 * (tb - ta)), z);
        while (true) {
            double next = tb;
            int to = -1;
            if (k >= 0)
                for (std::size_t b = 0; b < items_.items.size(); ++b) {
                    const KeepOutItem& B = items_.items[b];
                    if (int(b) == k || B.height > z + kHeightSlack) continue;
                    const Eigen::Vector2d ca = items_.items[std::size_t(k)].centre, cb = B.centre;
                    const double rate = 2 * d.dot(cb - ca);
                    if (rate <= 0) continue;  // moving away from b's side of the bisector
                    const double tc = (cb.squaredNorm() - ca.squaredNorm() - 2 * P.dot(cb - ca)) / rate;
                    if (tc > t + 1e-12 && tc < next) next = tc, to = int(b);
                }
            if (!pieces_.empty() && pieces_.back().second == k) pieces_.back().first = next;
            else pieces_.push_back({next, k});
            if (to < 0) break;
            t = next;
            k = to;
        }
    }
}

void KeepOutStage::turn_in_place(const ToolMove& mv, const Eigen::Vector3d& at, double target, double shift, double e_at) {
    const Joint& J = kin_.machine().joints[std::size_t(r_)];
    const double q = target + shift;
    if (q < J.min - 1e-9 || q > J.max + 1e-9) {
        // Reported as a limit hit: the look-back then unwinds on the travel move before.
        moves_.refused_at_limit = true;
        std::ostringstream s;
        s << "R would turn to " << q << " (limits " << J.min << " .. " << J.max
          << ") while printing; add a travel move before this line where it can unwind";
        throw LineError(mv.column, s.str());
    }
    ToolMove turn = mv;
    turn.any_xyz = false;
    turn.tip = at;
    turn.e.reset();
    turn.f.reset();
    turn.e_position = e_at;
    turn.commanded = 0;  // send names R alone
    send(turn, target, true);
}

const KeepOutMoves& KeepOutStage::tool_move(const ToolMove& mv) {
    moves_.steps.clear();
    moves_.refusal.reset();
    moves_.refused_at_limit = false;
    // Everything is read from the state as it is before the move (no move made here has run yet),
    // so the moves can be made first and run after.
    try {
        make_moves(mv);
    } catch (const LineError& e) {
        moves_.refusal = e;
    }
    return moves_;
}

void KeepOutStage::make_moves(const ToolMove& mv) {
    if (mv.any_rotary) throw LineError(mv.column, "with --keep-out R is computed from the path: the input must not turn it");
    if (mv.mode != OrientationMode::Angles) throw LineError(mv.column, "--keep-out works in angle form (G43.4)");
    const Eigen::Vector3d p1 = state_.pose.tip, p2 = mv.tip;
    const Eigen::Vector2d d = (p2 - p1).head<2>();
    if (items_.items.empty() || !state_.tip_known || !mv.any_xyz || d.norm() < kNoDirection) {
        moves_.steps.push_back({mv, false});
        return;
    }
    angles_.programmed(state_, current_);
    const double r_now = current_[std::size_t(r_)];
    const double shift = state_.q[std::size_t(r_)] - r_now;  // programmed R -> joint (one rotary: no flip)
    const bool prints = extrudes(mv.e, mv.e_relative, mv.e_position);
    if (!prints) {
        // A travel move: R at its end, reached along the move; the planner and the look-back may
        // end it on another turn inside the limits (unwinding).
        const int k = nearest(p2.head<2>(), p2.z());
        if (k < 0) {
            moves_.steps.push_back({mv, false});
            return;
        }
        send(mv, continuous(r_now, normal_toward(p2.head<2>(), d, k, mv.column), p2.head<2>(), k, -1, shift));
        return;
    }

    find_pieces(p1, p2);

    // Each piece: turn in place to its R where it differs, then the piece with its share of E.
    double t0 = 0, r = r_now, e_at = mv.e_position, e_sent = 0;
    int before = pieces_.front().second;
    ToolMove piece = mv;
    for (std::size_t i = 0; i < pieces_.size(); ++i) {
        const auto [t1, k] = pieces_[i];
        const bool last = i + 1 == pieces_.size();
        const Eigen::Vector3d at = p1 + (p2 - p1) * t0;
        if (k >= 0) {
            const double target = continuous(r, normal_toward(at.head<2>(), d, k, mv.column), at.head<2>(), before, k, shift);
            if (std::abs(target - r) > 1e-9) {
                turn_in_place(mv, at, target, shift, e_at);
                r = target;
            }
        }
        piece.tip = p1 + (p2 - p1) * t1;
        piece.any_xyz = true;
        piece.e_position = e_at;
        if (i > 0) piece.f.reset();
        if (!last) {
            // Rounded as written (5 decimals), so that relative pieces add up to the move's E exactly.
            const double share = std::round((mv.e->value - (mv.e_relative ? 0.0 : mv.e_position)) * (t1 - t0) * 1e5) / 1e5;
            piece.e = PassedNumber{mv.e_relative ? share : e_at + share, {}, 5};
            e_sent += share;
        } else {
            piece.e = mv.e;
            if (mv.e_relative && i > 0) piece.e = PassedNumber{mv.e->value - e_sent, {}, 5};
        }
        send(piece, r);
        if (!mv.e_relative) e_at = piece.e->value;
        t0 = t1;
        before = k;
    }
}

}  // namespace xlate5
