// SPDX-License-Identifier: GPL-3.0-or-later
// The kinematic-error report and the log that holds measured moves for it. What it may call: see report.hpp.
#include "translators/inspect/report.hpp"

#include "translators/machine/machine.hpp"
#include "translators/pipeline/motion.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace xlate5 {

namespace {

constexpr double kLogMin = -7, kLogMax = 3;

// JSON has no inf or NaN: an infinite value is written as 1e999 (a valid JSON number that
// parsers read as infinity), NaN as null.
std::string num(double v) {
    if (std::isnan(v)) return "null";
    if (std::isinf(v)) return v > 0 ? "1e999" : "-1e999";
    char b[48];
    std::snprintf(b, sizeof b, "%.6g", v);
    return b;
}

std::string escape(const std::string& s) {
    std::string o;
    for (char c : s) {
        if (c == '"' || c == '\\') o += '\\';
        if (static_cast<unsigned char>(c) < 0x20) {
            char b[8];
            std::snprintf(b, sizeof b, "\\u%04x", c);
            o += b;
            continue;
        }
        o += c;
    }
    return o;
}

// Text inside an SVG element: XML's rules (the JSON escape above lets '&' and '<' through). A
// control byte is not allowed in XML 1.0 at all: shown as U+FFFD.
std::string xml_escape(const std::string& s) {
    std::string o;
    for (char c : s) {
        switch (c) {
            case '&': o += "&amp;"; break;
            case '<': o += "&lt;"; break;
            case '>': o += "&gt;"; break;
            case '"': o += "&quot;"; break;
            case '\'': o += "&apos;"; break;
            default:
                if (static_cast<unsigned char>(c) < 0x20 && c != '\t') o += "\xEF\xBF\xBD";
                else o += c;
        }
    }
    return o;
}

}  // namespace

void DeviationReport::Distribution::add(double v, std::uint64_t line) {
    ++count;
    sum += v;
    if (v > max || count == 1) {
        max = std::max(max, v);
        max_line = line;
    }
    if (!(v > 0)) {
        ++zeros;
        return;
    }
    // Range-checked before the cast (an infinite deviation would make it undefined): beyond the
    // top bin counts in the top bin.
    const double x = (std::log10(v) - kLogMin) / (kLogMax - kLogMin) * kBins;
    bins[x >= kBins - 1 ? std::size_t(kBins - 1) : x > 0 ? std::size_t(x) : 0]++;
}

double DeviationReport::Distribution::percentile(double p) const {
    if (count == 0) return 0;
    const double want = p * double(count);
    double seen = double(zeros);
    if (seen >= want) return 0;
    for (int i = 0; i < kBins; ++i) {
        seen += double(bins[std::size_t(i)]);
        if (seen >= want) return std::min(max, std::pow(10.0, kLogMin + (i + 1) * (kLogMax - kLogMin) / kBins));  // bin's upper edge
    }
    return max;
}

std::string DeviationReport::Distribution::json() const {
    return "{\"max\": " + num(max) + ", \"max_at_line\": " + std::to_string(max_line) + ", \"mean\": " +
           num(count ? sum / double(count) : 0.0) + ", \"p50\": " + num(percentile(0.5)) + ", \"p95\": " + num(percentile(0.95)) +
           ", \"p99\": " + num(percentile(0.99)) + ", \"moves\": " + std::to_string(count) + "}";
}

DeviationReport::DeviationReport(std::string file, std::string machine, double tolerance, double angle_tolerance)
    : file_(std::move(file)), machine_(std::move(machine)), tolerance_(tolerance), angle_tolerance_(angle_tolerance) {}

void DeviationReport::add_move(std::uint64_t line, double tip, double angle, double feed_error, int pieces) {
    ++moves_;
    pieces_ += std::uint64_t(pieces);
    if (pieces > 1) ++split_moves_;
    tip_.add(tip, line);
    angle_.add(angle, line);
    feed_.add(std::abs(feed_error), line);
    // The series: each point the worst of `bucket_` consecutive moves; when full, pairs merge.
    if (in_bucket_ == 0) series_.push_back({line, line, tip, angle});
    Point& p = series_.back();
    p.last_line = line;
    p.tip = std::max(p.tip, tip);
    p.angle = std::max(p.angle, angle);
    if (++in_bucket_ == bucket_) in_bucket_ = 0;
    if (series_.size() > kMaxPoints && in_bucket_ == 0) {
        std::vector<Point> merged;
        for (std::size_t i = 0; i < series_.size(); i += 2) {
            Point m = series_[i];
            if (i + 1 < series_.size()) {
                m.last_line = series_[i + 1].last_line;
                m.tip = std::max(m.tip, series_[i + 1].tip);
                m.angle = std::max(m.angle, series_[i + 1].angle);
            }
            merged.push_back(m);
        }
        series_.swap(merged);
        bucket_ *= 2;
    }
}

void DeviationReport::add_rotary_travel(char joint, double degrees) {
    for (auto& [j, d] : travel_)
        if (j == joint) {
            d += degrees;
            return;
        }
    travel_.emplace_back(joint, degrees);
}

void DeviationReport::add_joint_range(char joint, double low, double high) {
    for (auto& r : ranges_)
        if (r.joint == joint) {
            r.low = std::min(r.low, low);
            r.high = std::max(r.high, high);
            return;
        }
    ranges_.push_back({joint, low, high});
}

void DeviationReport::add_marks(std::uint64_t line, std::uint64_t moves_written, int pole_crossings, int change, int rezeros) {
    rezeros_ += std::uint64_t(std::max(rezeros, 0));
    const auto keep = [&](MarkKind kind, int times) {
        for (int i = 0; i < times && marks_.size() < kMaxMarks; ++i) marks_.push_back({kind, line, moves_written});
    };
    keep(MarkKind::PoleCrossing, pole_crossings);
    keep(MarkKind::Unwind, change == int(SolutionChange::Turns));
    keep(MarkKind::BranchChange, change == int(SolutionChange::Branch));
    keep(MarkKind::Rezero, rezeros);
}

std::string DeviationReport::json() const {
    std::string o = "{\n";
    o += "  \"file\": \"" + escape(file_) + "\",\n";
    o += "  \"machine\": \"" + escape(machine_) + "\",\n";
    o += "  \"tolerance_mm\": " + num(tolerance_) + ",\n";
    o += "  \"angle_tolerance_deg\": " + num(angle_tolerance_) + ",\n";
    o += "  \"lines_in\": " + std::to_string(lines_in_) + ",\n";
    o += "  \"lines_out\": " + std::to_string(lines_out_) + ",\n";
    o += "  \"moves\": " + std::to_string(moves_) + ",\n";
    o += "  \"moves_split\": " + std::to_string(split_moves_) + ",\n";
    o += "  \"output_moves\": " + std::to_string(pieces_) + ",\n";
    o += "  \"pole_crossings\": " + std::to_string(pole_crossings_) + ",\n";
    o += "  \"half_turns\": " + std::to_string(half_turns_) + ",\n";
    o += "  \"tip_deviation_mm\": " + tip_.json() + ",\n";
    o += "  \"orientation_deviation_deg\": " + angle_.json() + ",\n";
    o += "  \"feed_error_relative\": " + feed_.json() + ",\n";
    o += "  \"rotary_travel_deg\": {";
    for (std::size_t i = 0; i < travel_.size(); ++i)
        o += std::string(i ? ", " : "") + "\"" + travel_[i].first + "\": " + num(travel_[i].second);
    o += "},\n";
    // The least travel any plan within the tolerance could have (planner.cpp: a bound by dynamic
    // programming over the programmed axes' solutions), and the travel over it.
    if (rotary_bound_ >= 0) {
        double travel = 0;
        for (const auto& t : travel_) travel += t.second;
        o += "  \"rotary_travel_total_deg\": " + num(travel) + ",\n";
        o += "  \"rotary_travel_lower_bound_deg\": " + num(rotary_bound_) + ",\n";
        o += "  \"rotary_travel_ratio\": " + (rotary_bound_ > 0 ? num(travel / rotary_bound_) : std::string("null")) + ",\n";
    }
    o += "  \"printing_moves_turning_over_90_deg\": " + std::to_string(printing_turns_) + ",\n";
    if (collision_checked_) {
        o += "  \"collisions\": {\"count\": " + std::to_string(collision_count_) + ", \"list\": [";
        for (std::size_t i = 0; i < collisions_.size(); ++i) o += std::string(i ? ", " : "") + "\"" + escape(collisions_[i]) + "\"";
        o += "]},\n";
        o += "  \"rerouted\": {\"count\": " + std::to_string(reroute_count_) + ", \"list\": [";
        for (std::size_t i = 0; i < reroutes_.size(); ++i) o += std::string(i ? ", " : "") + "\"" + escape(reroutes_[i]) + "\"";
        o += "]},\n";
    }
    // Extremes over the translated tool-space moves (joint-space G49 moves are passed on as written).
    o += "  \"joint_range\": {";
    for (std::size_t i = 0; i < ranges_.size(); ++i)
        o += std::string(i ? ", " : "") + "\"" + ranges_[i].joint + "\": {\"min\": " + num(ranges_[i].low) + ", \"max\": " + num(ranges_[i].high) + "}";
    o += "},\n";
    // At the feeds written, without acceleration: a lower bound of the print's duration.
    o += "  \"estimated_minutes\": " + num(minutes_) + ",\n";
    o += written_;
    o += "  \"unwinds\": " + std::to_string(turns_) + ",\n";
    o += "  \"rezeros\": " + std::to_string(rezeros_) + ",\n";
    o += "  \"branch_changes\": " + std::to_string(branches_) + "\n}\n";
    return o;
}

namespace {

// A step of 1, 2 or 5 times a power of ten giving about `count` ticks over `range`.
double nice_step(double range, int count) {
    const double raw = range / count;
    const double decade = std::pow(10.0, std::floor(std::log10(raw)));
    for (double m : {1.0, 2.0, 5.0})
        if (m * decade >= raw) return m * decade;
    return 10 * decade;
}

// A tick label as a person writes it: 0.001, 0.01, 2500, 1e-05 only below 0.0001.
std::string tick_text(double v) {
    char b[48];
    if (v != 0 && std::abs(v) < 1e-4) std::snprintf(b, sizeof b, "%.0e", v);
    else std::snprintf(b, sizeof b, "%.10g", v);
    return b;
}

}  // namespace

std::string DeviationReport::svg() const {
    // Tip deviation (mm) along the file on a log scale (deviations span decades, the tolerance
    // among them), with the tolerance as a line; 900 x 300 plot area.
    const double W = 900, H = 300, left = 80, top = 30;
    double vmax = std::max(tolerance_, tip_.max), vmin = tolerance_ / 100;
    for (const Point& p : series_)
        if (p.tip > 0) vmin = std::min(vmin, p.tip);
    if (!(vmax > 0) || !std::isfinite(vmax)) vmax = std::pow(10.0, kLogMax);  // an infinite deviation is drawn at the top
    if (!(vmin > 0)) vmin = vmax / 1e3;
    // At most four decades under the tolerance: below that a deviation is nothing to look at.
    const double lo = std::max({kLogMin, std::floor(std::log10(vmin)), std::floor(std::log10(tolerance_)) - 4}), hi = std::max(lo + 1, std::ceil(std::log10(vmax) + 1e-9));
    const double first = series_.empty() ? 0 : double(series_.front().first_line);
    const double last = series_.empty() ? 1 : std::max(double(series_.back().last_line), first + 1);
    auto X = [&](double line) { return left + (line - first) / (last - first) * W; };
    auto Y = [&](double v) {  // zero and below the range at the bottom
        const double l = v > 0 ? std::clamp(std::log10(v), lo, hi) : lo;
        return top + H - (l - lo) / (hi - lo) * H;
    };
    const std::string font = "font-family=\"sans-serif\" font-size=\"11\"";
    std::string o;
    o += "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" + num(W + left + 30) + "\" height=\"" + num(H + top + 60) + "\">\n";
    o += "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
    o += "<text x=\"" + num(left) + "\" y=\"18\" font-family=\"sans-serif\" font-size=\"13\">" + xml_escape(file_) + " on " +
         xml_escape(machine_) + ": largest tip deviation from the programmed path per move (max " + num(tip_.max) + " mm at line " +
         std::to_string(tip_.max_line) + ")</text>\n";
    // Decades on the deviation axis, with grid lines; the x axis in 1-2-5 steps of input lines.
    for (double d = lo; d <= hi + 1e-9; d += 1) {
        const double v = std::pow(10.0, d);
        o += "<line class=\"grid\" x1=\"" + num(left) + "\" y1=\"" + num(Y(v)) + "\" x2=\"" + num(left + W) + "\" y2=\"" + num(Y(v)) +
             "\" stroke=\"#ddd\"/>\n";
        o += "<text class=\"ytick\" x=\"" + num(left - 6) + "\" y=\"" + num(Y(v) + 4) + "\" " + font + " text-anchor=\"end\">" + tick_text(v) +
             "</text>\n";
    }
    const double step = nice_step(last - first, 8);
    for (double l = std::ceil(first / step) * step; l <= last + 1e-9; l += step) {
        o += "<line x1=\"" + num(X(l)) + "\" y1=\"" + num(top + H) + "\" x2=\"" + num(X(l)) + "\" y2=\"" + num(top + H + 5) +
             "\" stroke=\"black\"/>\n";
        o += "<text class=\"xtick\" x=\"" + num(X(l)) + "\" y=\"" + num(top + H + 18) + "\" " + font + " text-anchor=\"middle\">" +
             tick_text(l) + "</text>\n";
    }
    o += "<line x1=\"" + num(left) + "\" y1=\"" + num(top + H) + "\" x2=\"" + num(left + W) + "\" y2=\"" + num(top + H) + "\" stroke=\"black\"/>\n";
    o += "<line x1=\"" + num(left) + "\" y1=\"" + num(top) + "\" x2=\"" + num(left) + "\" y2=\"" + num(top + H) + "\" stroke=\"black\"/>\n";
    o += "<text x=\"16\" y=\"" + num(top + H / 2) + "\" font-family=\"sans-serif\" font-size=\"12\" text-anchor=\"middle\" transform=\"rotate(-90 16 " +
         num(top + H / 2) + ")\">tip deviation, mm (log scale)</text>\n";
    o += "<text x=\"" + num(left + W / 2) + "\" y=\"" + num(top + H + 40) +
         "\" font-family=\"sans-serif\" font-size=\"12\" text-anchor=\"middle\">input line (red: tolerance " + num(tolerance_) + " mm)</text>\n";
    o += "<line x1=\"" + num(left) + "\" y1=\"" + num(Y(tolerance_)) + "\" x2=\"" + num(left + W) + "\" y2=\"" + num(Y(tolerance_)) +
         "\" stroke=\"red\" stroke-dasharray=\"6,4\"/>\n";
    o += "<polyline fill=\"none\" stroke=\"steelblue\" stroke-width=\"1\" points=\"";
    for (const Point& p : series_) o += num(X(0.5 * double(p.first_line + p.last_line))) + "," + num(Y(p.tip)) + " ";
    o += "\"/>\n</svg>\n";
    return o;
}

void MoveLog::add(std::uint64_t line, const MoveResult& m) {
    bool half_turn = false, printing_turn = false;
    for (std::size_t j = 0; j < m.travel.size(); ++j) {
        if (!machine_.joints[j].rotary) continue;
        half_turn = half_turn || m.travel[j] >= DeviationReport::kHalfTurnDeg;
        printing_turn = printing_turn || (m.prints && m.travel[j] > DeviationReport::kPrintingTurnDeg);
        if (hold_) held_.travel.emplace_back(machine_.joints[j].name, m.travel[j]);
        else report_.add_rotary_travel(machine_.joints[j].name, m.travel[j]);
    }
    const std::size_t n = machine_.joints.size();
    const bool ranged = m.low.size() == n && m.high.size() == n;
    if (hold_) {
        held_.moves.push_back({line, m.tip_error, m.angle_error, m.feed_error, m.pieces, held_.travel.size(), m.minutes, int(m.change), m.pole_crossings, half_turn,
                               m.rezeros, printing_turn, m.moves_written, true});
        for (std::size_t j = 0; j < n; ++j) held_.ranges.push_back(ranged ? m.low[j] : NAN);
        for (std::size_t j = 0; j < n; ++j) held_.ranges.push_back(ranged ? m.high[j] : NAN);
        return;
    }
    report_.add_move(line, m.tip_error, m.angle_error, m.feed_error, m.pieces);
    ranges_.clear();
    for (std::size_t j = 0; j < n; ++j) ranges_.push_back(ranged ? m.low[j] : NAN);
    for (std::size_t j = 0; j < n; ++j) ranges_.push_back(ranged ? m.high[j] : NAN);
    add_rest(ranges_.data(), m.minutes, int(m.change));
    report_.add_route(m.pole_crossings, half_turn, printing_turn);
    report_.add_marks(line, m.moves_written, m.pole_crossings, int(m.change), m.rezeros);
}

void MoveLog::add_rezeros(std::uint64_t line, std::uint64_t moves_written, int rezeros) {
    if (!hold_) {
        report_.add_marks(line, moves_written, 0, int(SolutionChange::None), rezeros);
        return;
    }
    held_.moves.push_back({line, 0, 0, 0, 0, held_.travel.size(), 0, int(SolutionChange::None), 0, false, rezeros, false, moves_written, false});
    held_.ranges.insert(held_.ranges.end(), 2 * machine_.joints.size(), NAN);
}

void MoveLog::drop_held_from(std::size_t moves) {
    if (moves >= held_.moves.size()) return;
    held_.travel.resize(moves == 0 ? 0 : held_.moves[moves - 1].travel_end);
    held_.ranges.resize(moves * 2 * machine_.joints.size());
    held_.moves.resize(moves);
}

void MoveLog::add_rest(const double* ranges, double minutes, int change) {
    const std::size_t n = machine_.joints.size();
    for (std::size_t j = 0; j < n; ++j)
        if (!std::isnan(ranges[j])) report_.add_joint_range(machine_.joints[j].name, ranges[j], ranges[n + j]);
    report_.add_time(minutes);
    report_.add_solution_change(change == int(SolutionChange::Turns), change == int(SolutionChange::Branch));
}

void MoveLog::release(std::size_t moves) {
    if (moves == 0) return;
    const std::size_t travel_end = held_.moves[moves - 1].travel_end;
    const std::size_t n = machine_.joints.size();
    for (std::size_t i = 0, t = 0; i < moves; ++i) {
        const Pending& m = held_.moves[i];
        if (m.measured) {
            report_.add_move(m.line, m.tip, m.angle, m.feed, m.pieces);
            report_.add_route(m.pole_crossings, m.half_turn, m.printing_turn);
            add_rest(&held_.ranges[i * 2 * n], m.minutes, m.change);
        }
        report_.add_marks(m.line, m.moves_written, m.pole_crossings, m.change, m.rezeros);
        for (; t < m.travel_end; ++t) report_.add_rotary_travel(held_.travel[t].first, held_.travel[t].second);
    }
    held_.ranges.erase(held_.ranges.begin(), held_.ranges.begin() + std::ptrdiff_t(moves * 2 * n));
    held_.moves.erase(held_.moves.begin(), held_.moves.begin() + std::ptrdiff_t(moves));
    held_.travel.erase(held_.travel.begin(), held_.travel.begin() + std::ptrdiff_t(travel_end));
    for (Pending& m : held_.moves) m.travel_end -= travel_end;
}

}  // namespace xlate5
