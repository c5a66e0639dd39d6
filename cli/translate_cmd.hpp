// `xlate5 --machine M [-i IN] [-o OUT] ...`: the translation, forward or --inverse (stage: command
// line; may call the translators' public API: machine, kinematics, translator, stream, report).
#pragma once
#include <CLI/CLI.hpp>
#include <string>

#include "cli/errors.hpp"

namespace xlate5::cli {

struct TranslateOptions {
    std::string input = "-", output = "-", mode, preview = "G43.4", extruder = "E", report, plot, compensation, preview_html;
    bool inverse = false, no_segment = false, compact_words = false, no_progress = false;
    double tolerance = 0, angle_tolerance = 0;
    // Other inputs: CL data and waypoint tables (input_front), keep-out items (keep_out).
    std::string input_format = "auto", keep_out;
    double extrusion_per_mm = 0, waypoint_feed = 1200;
};

// The translation's options live on the top-level command: translating is what xlate5 does
// when no subcommand is given.
void add_translate_options(CLI::App& app, TranslateOptions& o);
int run_translate(const Common& common, const TranslateOptions& o);

}  // namespace xlate5::cli
