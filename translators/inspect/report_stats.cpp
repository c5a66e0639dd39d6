// SPDX-License-Identifier: GPL-3.0-or-later
// The report's deviation statistics. What it may call: see report_stats.hpp.
#include "translators/inspect/report_stats.hpp"

#include <algorithm>
#include <cmath>

#include "translators/inspect/report_json.hpp"

namespace xlate5 {

void Distribution::add(double v, std::uint64_t line) {
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

double Distribution::percentile(double p) const {
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

std::string Distribution::json() const {
    return "{\"max\": " + json_number(max) + ", \"max_at_line\": " + std::to_string(max_line) + ", \"mean\": " +
           json_number(count ? sum / double(count) : 0.0) + ", \"p50\": " + json_number(percentile(0.5)) + ", \"p95\": " +
           json_number(percentile(0.95)) + ", \"p99\": " + json_number(percentile(0.99)) + ", \"moves\": " + std::to_string(count) + "}";
}

void DeviationSeries::add(std::uint64_t line, double tip, double angle) {
    if (in_bucket_ == 0) points_.push_back({line, line, tip, angle});
    Point& p = points_.back();
    p.last_line = line;
    p.tip = std::max(p.tip, tip);
    p.angle = std::max(p.angle, angle);
    if (++in_bucket_ == bucket_) in_bucket_ = 0;
    if (points_.size() > kMaxPoints && in_bucket_ == 0) {
        std::vector<Point> merged;
        for (std::size_t i = 0; i < points_.size(); i += 2) {
            Point m = points_[i];
            if (i + 1 < points_.size()) {
                m.last_line = points_[i + 1].last_line;
                m.tip = std::max(m.tip, points_[i + 1].tip);
                m.angle = std::max(m.angle, points_[i + 1].angle);
            }
            merged.push_back(m);
        }
        points_.swap(merged);
        bucket_ *= 2;
    }
}

void MoveStats::add(std::uint64_t line, double tip_error, double angle_error, double feed_error, int move_pieces) {
    ++moves;
    pieces += std::uint64_t(move_pieces);
    if (move_pieces > 1) ++split_moves;
    tip.add(tip_error, line);
    angle.add(angle_error, line);
    feed.add(std::abs(feed_error), line);
    series.add(line, tip_error, angle_error);
}

}  // namespace xlate5
