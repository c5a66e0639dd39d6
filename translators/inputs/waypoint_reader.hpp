// SPDX-License-Identifier: GPL-3.0-or-later
// A front end before the interpreter: the plain waypoint table that curved-layer research tools
// write, one point per line, `x y z nx ny nz` (blanks or commas between; millimetres; the vector
// is the tool axis from tip toward holder, any length but 0, normalised here) -> canonical G43.5
// G-code lines under the table's own line numbers (see apt_reader.hpp for why G-code lines). The
// first point and the first after a blank line are reached by a travel move (G0); every other is
// printed from the one before with E = extrusion_per_mm x its length (relative E, M83) at `feed`.
// `#` and `;` start comments. Anything else is refused: file:line:column: cause.
// May call: number (formatting). Called by input_front.
#pragma once
#include <cstdint>
#include <string>
#include <string_view>

#include <Eigen/Core>

#include "translators/inputs/front_line.hpp"

namespace xlate5 {

struct WaypointOptions {
    std::string input_name = "<stdin>";
    double extrusion_per_mm = 0;  // E per mm of tip path
    double feed = 1200;           // mm/min of the printing moves
};

class WaypointReader {
public:
    explicit WaypointReader(WaypointOptions options);
    // One table line (without '\n'); throws InputError naming file, line and column.
    void read(std::string_view line, std::uint64_t line_no, FrontLines& out);

private:
    WaypointOptions o_;
    bool started_ = false, travel_next_ = true;
    Eigen::Vector3d tip_ = Eigen::Vector3d::Zero();
};

}  // namespace xlate5
