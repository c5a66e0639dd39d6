// SPDX-License-Identifier: GPL-3.0-or-later
// The report's deviation statistics: what each measured move adds (its tip, axis and feed
// errors, its pieces, its time), held in bounded memory whatever the file size (histograms, and
// a series that halves its resolution as it grows). Part of DeviationReport (report.hpp).
#pragma once
#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace xlate5 {

// Counts in logarithmic bins (1e-7 .. 1e3), for percentiles without keeping every value.
struct Distribution {
    static constexpr int kBins = 200;
    static constexpr double kLogMin = -7, kLogMax = 3;
    std::array<std::uint64_t, kBins> bins{};
    std::uint64_t count = 0, zeros = 0;
    double max = 0, sum = 0;
    std::uint64_t max_line = 0;
    void add(double v, std::uint64_t line);
    double percentile(double p) const;
    std::string json() const;
};

// The tip and axis deviation along the file for the plot: each point the worst of `bucket`
// consecutive moves; when full, pairs merge and the bucket doubles.
class DeviationSeries {
public:
    struct Point {
        std::uint64_t first_line, last_line;
        double tip, angle;
    };
    static constexpr std::size_t kMaxPoints = 2000;
    void add(std::uint64_t line, double tip, double angle);
    const std::vector<Point>& points() const { return points_; }

private:
    std::vector<Point> points_;  // at most kMaxPoints
    std::uint64_t bucket_ = 1, in_bucket_ = 0;
};

// What the measured moves add up to.
struct MoveStats {
    // One input move: its largest sampled tip (mm) and axis (degrees) deviation, its feed error
    // (relative: tip speed the firmware will produce over the programmed speed, minus 1), and
    // how many output moves it became.
    void add(std::uint64_t line, double tip, double angle, double feed_error, int pieces);
    std::uint64_t moves = 0, split_moves = 0, pieces = 0;
    double minutes = 0;  // at the feeds written, without acceleration
    Distribution tip, angle, feed;
    DeviationSeries series;
};

}  // namespace xlate5
