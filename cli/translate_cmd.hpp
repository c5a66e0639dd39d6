// SPDX-License-Identifier: GPL-3.0-or-later
// `xlate5 --machine M [-i IN] [-o OUT] ...`: the translation, forward or --inverse (stage: command
// line; may call the translators' public API: machine, kinematics, translator, stream, report).
#pragma once
#include <CLI/CLI.hpp>
#include <cstdint>
#include <string>
#include <vector>

#include "cli/errors.hpp"

namespace xlate5::cli {

struct TranslateOptions {
    std::string input = "-", output = "-", mode, preview = "G43.4", extruder = "E", report, plot, compensation, preview_html;
    bool inverse = false, no_segment = false, compact_words = false, no_progress = false, keep_slicer_times = false;
    double baud = 115200;  // the serial link the pre-flight estimate budgets
    double tolerance = 0, angle_tolerance = 0;
    // Other inputs: CL data and waypoint tables (input_front), keep-out items (keep_out).
    std::string input_format = "auto", keep_out;
    double extrusion_per_mm = 0, waypoint_feed = 1200;
    // Slicer post-processing: FILE translated in place; --force translates a file that already
    // carries xlate5's header of the same space (provenance.hpp).
    std::string file;
    bool force = false;
    // Retargeting: the input is joint-space G-code written for this machine (--from).
    std::string from;
    std::vector<double> place;  // --place X,Y,Z: the source's part frame on this machine
    // The collision check of a machine with [[bodies]]: refuse, warn or off.
    std::string collision = "refuse";
    std::string reroute;  // "", "on" or "off"
    double lift = 0;      // 0: the machine file's
};

// Input made by another command (join): the lines of `fd`, each traced back to the file and
// line it comes from, so that errors name those.
struct SourceLine {
    std::string file;
    std::uint64_t line = 0;
    bool inserted = false;  // written by the command itself (before that line)
};
struct MadeInput {
    int fd = -1;
    std::vector<SourceLine> origin;  // per line, from line 1
};

// The translation's options live on the top-level command: translating is what xlate5 does
// when no subcommand is given.
void add_translate_options(CLI::App& app, TranslateOptions& o);
int run_translate(const Common& common, const TranslateOptions& o, const MadeInput* made = nullptr);

}  // namespace xlate5::cli
