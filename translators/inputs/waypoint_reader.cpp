// SPDX-License-Identifier: GPL-3.0-or-later
// The waypoint-table front end: `x y z nx ny nz` lines -> canonical G43.5 G-code lines.
// What it may call: see waypoint_reader.hpp.
#include "translators/inputs/waypoint_reader.hpp"

#include <charconv>
#include <cmath>

#include "translators/error.hpp"
#include "translators/inputs/gcode_lexer.hpp"

namespace xlate5 {

WaypointReader::WaypointReader(WaypointOptions options) : o_(std::move(options)) {}

void WaypointReader::read(std::string_view line, std::uint64_t line_no, FrontLines& out) {
    auto fail = [&](std::size_t at, const std::string& why) { throw InputError(o_.input_name, line_no, std::uint32_t(at + 1), why); };
    const std::size_t hash = line.find_first_of("#;");
    const std::string_view body = line.substr(0, hash);
    double v[6];
    int n = 0;
    std::size_t i = 0;
    while (true) {
        while (i < body.size() && (body[i] == ' ' || body[i] == '\t' || body[i] == ',' || body[i] == '\r')) ++i;
        if (i >= body.size()) break;
        std::size_t j = i;
        while (j < body.size() && body[j] != ' ' && body[j] != '\t' && body[j] != ',' && body[j] != '\r') ++j;
        std::string_view t = body.substr(i, j - i);
        if (n == 6) fail(i, "a waypoint has 6 numbers: x y z nx ny nz");
        if (!t.empty() && t.front() == '+') t.remove_prefix(1);
        double x = 0;
        const auto [end, ec] = std::from_chars(t.data(), t.data() + t.size(), x);
        if (ec != std::errc() || end != t.data() + t.size() || t.empty()) {
            // Built by append: GCC 12 warns (-Wrestrict) on "'" + std::string(...) here.
            std::string why = "'";
            why.append(body.substr(i, j - i)).append("' is not a number");
            fail(i, why);
        }
        // Range-checked as the G-code lexer checks its numbers.
        if (!std::isfinite(x) || std::abs(x) > kMaxNumber) fail(i, "number beyond +-1e9");
        v[n++] = x;
        i = j;
    }
    if (n == 0) {
        if (hash == std::string_view::npos) travel_next_ = true;  // a blank line ends a path
        if (hash != std::string_view::npos) out.push_back({line_no, "; " + std::string(line.substr(hash + 1))});
        return;
    }
    if (n != 6) fail(body.size(), "a waypoint has 6 numbers: x y z nx ny nz (" + std::to_string(n) + " here)");
    const Eigen::Vector3d tip(v[0], v[1], v[2]), axis(v[3], v[4], v[5]);
    if (!(axis.norm() > 1e-9)) fail(0, "the vector nx ny nz has length 0");
    if (!started_) {
        started_ = true;
        out.push_back({line_no, "G43.5"});
        out.push_back({line_no, "G90"});
        out.push_back({line_no, "G21"});
        out.push_back({line_no, "M83"});
    }
    std::string g = travel_next_ ? "G0" : "G1";
    for (int k = 0; k < 3; ++k) append_word(g, char('X' + k), tip[k], 6);
    const Eigen::Vector3d u = axis.normalized();
    for (int k = 0; k < 3; ++k) append_word(g, char('I' + k), u[k], 9);
    if (!travel_next_) {
        if (o_.extrusion_per_mm > 0) append_word(g, 'E', (tip - tip_).norm() * o_.extrusion_per_mm, 6);
        append_word(g, 'F', o_.feed, 3);
    }
    out.push_back({line_no, std::move(g)});
    tip_ = tip;
    travel_next_ = false;
}

}  // namespace xlate5
