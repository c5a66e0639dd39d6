// SPDX-License-Identifier: GPL-3.0-or-later
// A front end before the interpreter: APT / Siemens NX CLSF cutter-location records -> canonical
// tool-space G-code (G43.5: X Y Z tip, I J K tool axis), each line under the line number of the
// record it comes from. Why G-code lines and not typed moves: fed through the front door like any
// G-code line, the records get the interpreter's modes (G20 inches, G0/G1, F), the planner's
// solution choice and limits, the look-back (which replays input lines) and the report without a
// hook in any of them, and an error anywhere names the record's file and line.
// Records understood: GOTO/x,y,z[,i,j,k] (the axis modal; +Z until one is given), RAPID (the next
// GOTO only), FEDRAT/[IPM|MMPM,]f or FEDRAT/f[,IPM|MMPM], CIRCLE/xc,yc,zc,i,j,k,r[,...] (the next
// GOTO ends an arc about that axis, counterclockwise about it, cut into chords here), UNITS/
// INCHES|MM, MULTAX[/ON|OFF], LOAD/TOOL,n, $$ comments, TOOL PATH/ ... END-OF-PATH, FINI, and
// records that only draw or describe (PAINT, TLDATA, MSYS: coordinates are taken as given, in the
// program's frame), written as comments. Anything else is refused: file:line:column: cause.
// May call: number (formatting). Called by input_front.
#pragma once
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "translators/inputs/front_line.hpp"

namespace xlate5 {

struct AptOptions {
    std::string input_name = "<stdin>";
    double extrusion_per_mm = 0;  // E per mm of tip path on feed moves (0: none, cutting data)
    double chord_tolerance = 0.005;  // mm, sagitta of an arc's chords
    int extrusion_decimals = 5;      // the firmware's: E in mm is written at these, the rounding carried on
};

// Records before the first UNITS or FEDRAT are held until the unit is known (at most this many;
// then millimetres are assumed): NX writes the first RAPID GOTO before any FEDRAT.
inline constexpr std::size_t kAptHeldRecords = 10000;
// Turns of one helical CIRCLE (TIMES,n); its chords are bounded besides (1e6 an arc).
inline constexpr int kAptMaxTurns = 10000;

class AptReader {
public:
    explicit AptReader(AptOptions options);

    // One input line (without '\n'). Appends the G-code it stands for (possibly of held records
    // too). Throws InputError naming the file, line and column; the reader is then unchanged.
    void read(std::string_view line, std::uint64_t line_no, FrontLines& out);
    // End of input: releases held records; an unfinished continuation or CIRCLE is an error.
    void finish(std::uint64_t last_line, FrontLines& out);

private:
    struct State {
        std::optional<double> unit;  // mm per file unit, once known
        bool in_path = false, ended = false, rapid = false, multax = true;
        Eigen::Vector3d tip = Eigen::Vector3d::Zero(), axis = Eigen::Vector3d::UnitZ();
        bool tip_known = false;
        double e_carry = 0;  // mm of E the rounding to extrusion_decimals left to the next move
        std::optional<double> feed;  // in the file's length unit per minute
        bool feed_written = false;   // the G-code has had this F
        bool started = false;        // the preamble (G43.5, G90, M83) is out
        bool finished = false;       // FINI
        bool seen_record = false;    // a record other than NX's listing header has been read
        struct Circle {
            Eigen::Vector3d centre, axis;
            double radius;
            std::uint64_t line_no;
            int turns = 1;  // TIMES,n: the helix turns n - 1 times more than the arc to its GOTO
        };
        std::optional<Circle> circle;
        FrontLines held;  // records waiting for the unit
        std::string continued;  // a record ending in '$' continues on the next line
        std::uint64_t continued_line = 0;
    };
    void record(std::string_view text, std::uint64_t line_no, State& s, FrontLines& out) const;
    // record's kinds (apt_reader.cpp): a record split into its word and fields, then each kind.
    struct Record;
    void goto_record(const Record& r, State& s, FrontLines& out) const;
    void arc_to(const Record& r, const Eigen::Vector3d& tip, const Eigen::Vector3d& axis, State& s, FrontLines& out) const;
    void fedrat(const Record& r, State& s, FrontLines& out) const;
    void circle(const Record& r, State& s) const;
    // UNITS, MULTAX, LOAD, TOOL PATH, END-OF-PATH, FINI and the records kept as comments; false
    // when the record is none of them.
    bool setting(const Record& r, State& s, FrontLines& out) const;
    void set_unit(double mm, State& s, FrontLines& out) const;
    void emit(State& s, FrontLines& out, std::uint64_t line_no, std::string text) const;
    void go_to(const Eigen::Vector3d& tip, const Eigen::Vector3d& axis, std::uint64_t line_no, State& s, FrontLines& out) const;

    AptOptions o_;
    State s_;
};

// True when the first significant line of a file looks like CL data rather than G-code.
bool looks_like_apt(std::string_view line);

}  // namespace xlate5
