// SPDX-License-Identifier: GPL-3.0-or-later
// The report's JSON writer (--report FILE). What it may call: see report.hpp.
#include "translators/inspect/report_json.hpp"

#include <cmath>
#include <cstdio>

#include "translators/inspect/report.hpp"

namespace xlate5 {

std::string json_number(double v) {
    if (std::isnan(v)) return "null";
    if (std::isinf(v)) return v > 0 ? "1e999" : "-1e999";
    char b[48];
    std::snprintf(b, sizeof b, "%.6g", v);
    return b;
}

std::string json_escape(const std::string& s) {
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

std::string DeviationReport::json() const {
    std::string o = "{\n";
    o += "  \"file\": \"" + json_escape(file_) + "\",\n";
    o += "  \"machine\": \"" + json_escape(machine_) + "\",\n";
    o += "  \"tolerance_mm\": " + json_number(tolerance_) + ",\n";
    o += "  \"angle_tolerance_deg\": " + json_number(angle_tolerance_) + ",\n";
    o += "  \"lines_in\": " + std::to_string(lines_in_) + ",\n";
    o += "  \"lines_out\": " + std::to_string(lines_out_) + ",\n";
    o += "  \"moves\": " + std::to_string(stats.moves) + ",\n";
    o += "  \"moves_split\": " + std::to_string(stats.split_moves) + ",\n";
    o += "  \"output_moves\": " + std::to_string(stats.pieces) + ",\n";
    o += "  \"pole_crossings\": " + std::to_string(events.pole_crossings()) + ",\n";
    o += "  \"half_turns\": " + std::to_string(events.half_turns()) + ",\n";
    o += "  \"tip_deviation_mm\": " + stats.tip.json() + ",\n";
    o += "  \"orientation_deviation_deg\": " + stats.angle.json() + ",\n";
    o += "  \"feed_error_relative\": " + stats.feed.json() + ",\n";
    const auto& travel = joints.travel();
    const auto& ranges = joints.ranges();
    const double rotary_bound = joints.rotary_bound();
    o += "  \"rotary_travel_deg\": {";
    for (std::size_t i = 0; i < travel.size(); ++i)
        o += std::string(i ? ", " : "") + "\"" + travel[i].first + "\": " + json_number(travel[i].second);
    o += "},\n";
    // The least travel any plan within the tolerance could have (planner.cpp: a bound by dynamic
    // programming over the programmed axes' solutions), and the travel over it.
    if (rotary_bound >= 0) {
        double total = 0;
        for (const auto& t : travel) total += t.second;
        o += "  \"rotary_travel_total_deg\": " + json_number(total) + ",\n";
        o += "  \"rotary_travel_lower_bound_deg\": " + json_number(rotary_bound) + ",\n";
        o += "  \"rotary_travel_ratio\": " + (rotary_bound > 0 ? json_number(total / rotary_bound) : std::string("null")) + ",\n";
    }
    o += "  \"printing_moves_turning_over_90_deg\": " + std::to_string(events.printing_turns()) + ",\n";
    if (collisions.checked()) {
        for (const auto& [name, found] : {std::pair{"collisions", &collisions.collisions()}, std::pair{"rerouted", &collisions.reroutes()}}) {
            o += "  \"";
            o += name;
            o += "\": {\"count\": " + std::to_string(found->count) + ", \"list\": [";
            for (std::size_t i = 0; i < found->list.size(); ++i) o += std::string(i ? ", " : "") + "\"" + json_escape(found->list[i]) + "\"";
            o += "]},\n";
        }
    }
    // Extremes over the translated tool-space moves (joint-space G49 moves are passed on as written).
    o += "  \"joint_range\": {";
    for (std::size_t i = 0; i < ranges.size(); ++i)
        o += std::string(i ? ", " : "") + "\"" + ranges[i].joint + "\": {\"min\": " + json_number(ranges[i].low) + ", \"max\": " + json_number(ranges[i].high) + "}";
    o += "},\n";
    // At the feeds written, without acceleration: a lower bound of the print's duration.
    o += "  \"estimated_minutes\": " + json_number(stats.minutes) + ",\n";
    o += written_;
    o += "  \"unwinds\": " + std::to_string(events.unwinds()) + ",\n";
    o += "  \"rezeros\": " + std::to_string(events.rezeros()) + ",\n";
    o += "  \"branch_changes\": " + std::to_string(events.branch_changes()) + "\n}\n";
    return o;
}

}  // namespace xlate5
