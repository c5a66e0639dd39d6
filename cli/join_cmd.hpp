// SPDX-License-Identifier: GPL-3.0-or-later
// `xlate5 --machine M join base.gcode sub.gcode@I,J,K[@X,Y,Z] ... [-o OUT]`: one joint-space file
// from planar G-code files, each printed in the tilted plane of its build direction (the 3+2
// workflow of Coeytaux et al., WPI Worcester 2017, sec. 3.2.5 and 4.1.5: each sub-volume sliced
// planar along its own build direction, the files joined, separated by reorienting moves).
// Writes the files as one tool-space program, each inside G68.2 ... G69 with a safe change
// between them, and translates it like any input (stage: command line; may call translate_cmd
// and translators/work_plane for the plane's angles).
#pragma once
#include <CLI/CLI.hpp>
#include <memory>
#include <string>
#include <vector>

#include "cli/errors.hpp"
#include "cli/translate_cmd.hpp"

namespace xlate5::cli {

struct JoinCommand {
    CLI::App* join = nullptr;
    std::vector<std::string> parts;  // FILE[@I,J,K[@X,Y,Z]]
    double clearance = 5;            // mm along the tool
};

std::unique_ptr<JoinCommand> add_join_command(CLI::App& app);
// The exit code when `join` ran, -1 when it was not asked for. The translation's options
// (-o, --tolerance, --report ...) are the program's own.
int run_join_command(const JoinCommand& c, const Common& common, const TranslateOptions& translate);

}  // namespace xlate5::cli
