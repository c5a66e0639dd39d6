// SPDX-License-Identifier: GPL-3.0-or-later
// The provenance header and the refusals of binary and already translated input (stage: command
// line).
#include "cli/provenance.hpp"

namespace xlate5::cli {

namespace {
constexpr std::string_view kPrefix = "; xlate5 ";
constexpr std::string_view kJoint = " joint space";
constexpr std::string_view kTool = " tool space";

bool ends_with(std::string_view s, std::string_view tail) { return s.size() >= tail.size() && s.substr(s.size() - tail.size()) == tail; }
}  // namespace

std::string provenance_header(std::string_view version, std::string_view machine, Space space) {
    std::string h(kPrefix);
    h += version;
    h += " machine=";
    h += machine;
    h += space == Space::Joint ? kJoint : kTool;
    return h;
}

std::optional<Space> read_provenance(std::string_view line) {
    while (!line.empty() && (line.back() == '\r' || line.back() == ' ' || line.back() == '\t')) line.remove_suffix(1);
    if (line.substr(0, kPrefix.size()) != kPrefix || line.find(" machine=") == std::string_view::npos) return std::nullopt;
    if (ends_with(line, kJoint)) return Space::Joint;
    if (ends_with(line, kTool)) return Space::Tool;
    return std::nullopt;
}

bool is_binary_gcode(std::string_view first_line) { return first_line.substr(0, 4) == "GCDE"; }

std::string binary_gcode_message() {
    return "binary G-code (a .bgcode file, magic 'GCDE') cannot be translated: write text G-code instead "
           "(PrusaSlicer: Printer Settings > General > Firmware > untick 'Supports binary G-code', "
           "binary_gcode = 0)";
}

}  // namespace xlate5::cli
