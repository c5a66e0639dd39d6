// SPDX-License-Identifier: GPL-3.0-or-later
// The first stage after the line reader: chooses how input lines reach the front door. G-code
// goes straight in; APT / NX CLSF records (apt_reader) and waypoint tables (waypoint_reader)
// are turned into canonical G-code lines first, each fed under its record's own line number.
// `Auto` reads the first line that is not blank: CL data if it opens like a CL record, else
// G-code. An error in the G-code a record stands for is reported at the record (column 1) with
// the G-code quoted.
// May call: apt_reader, waypoint_reader, the front door (translator.hpp).
#pragma once
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

#include "translators/inputs/apt_reader.hpp"
#include "translators/inputs/front_line.hpp"
#include "translators/inputs/waypoint_reader.hpp"

namespace xlate5 {

class Translator;

enum class InputFormat { Auto, GCode, Apt, Waypoints };

// "auto", "gcode", "apt", "waypoints" (nullopt for anything else).
std::optional<InputFormat> parse_input_format(std::string_view name);

struct FrontOptions {
    InputFormat format = InputFormat::Auto;
    std::string input_name = "<stdin>";
    double extrusion_per_mm = 0;  // CL feed moves and waypoint moves: E per mm of tip path
    double waypoint_feed = 1200;  // mm/min
    double chord_tolerance = 0.005;  // mm, for CL arcs
    int extrusion_decimals = 5;      // the firmware's (Dialect): CL E is written at these
};

class InputFront {
public:
    InputFront(Translator& translator, FrontOptions options);
    ~InputFront();
    void feed(std::string_view line, std::uint64_t line_no, std::string& out);
    void finish(std::uint64_t last_line, std::string& out);
    InputFormat format() const { return format_; }
    Translator& translator() { return translator_; }

private:
    void pass(std::string& out);
    void feed_other(std::string_view line, std::uint64_t line_no, std::string& out);  // feed, but for G-code

    Translator& translator_;
    FrontOptions o_;
    InputFormat format_;
    std::unique_ptr<AptReader> apt_;
    std::unique_ptr<WaypointReader> waypoints_;
    FrontLines lines_;
};

}  // namespace xlate5
