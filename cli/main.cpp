// SPDX-License-Identifier: GPL-3.0-or-later
// xlate5: the command line's front door (stage: command line). Declares the commands, parses,
// and hands over to the one that was asked for: translate (no subcommand), machines, calibrate,
// pose, join, firmware-config, serve and ports. It may call cli/*_cmd and cli/man_page only; the commands call translators/
// and daemon/.
#include <CLI/CLI.hpp>
#include <filesystem>
#include <iostream>
#include <string>

#include "cli/calibrate_cmd.hpp"
#include "cli/errors.hpp"
#include "cli/firmware_cmd.hpp"
#include "cli/join_cmd.hpp"
#include "cli/machines_cmd.hpp"
#include "cli/man_page.hpp"
#include "cli/options.hpp"
#include "cli/pose_cmd.hpp"
#include "cli/serve_cmd.hpp"
#include "cli/translate_cmd.hpp"

#ifndef XLATE5_VERSION
#define XLATE5_VERSION "0.0.0"
#endif

using namespace xlate5::cli;

int main(int argc, char** argv) {
    // Named here rather than taken from argv[0], so help and the manual page read the same from
    // any path.
    CLI::App app{"xlate5: vendor-neutral 5-axis G-code -> joint-space G-code for a given machine", "xlate5"};
    app.set_version_flag("--version", std::string("xlate5 ") + XLATE5_VERSION);
    app.require_subcommand(0, 1);
    app.fallthrough();  // --machine may come after a subcommand too

    Common common;
    app.add_option("-m,--machine", common.machine, "machine name (see 'xlate5 machines') or path to a machine .toml")->option_text("NAME|PATH");
    app.add_option("--set", common.sets, "override a machine parameter, e.g. --set la=29 (repeatable)")->option_text("NAME=VALUE");
    TranslateOptions translate;
    add_translate_options(app, translate);
    auto* machines_cmd = app.add_subcommand("machines", "list the machines found (your own, the system's, the shipped ones)");
    const auto serve_cmds = add_serve_commands(app);
    const auto calibrate_cmds = add_calibrate_commands(app);
    const auto pose_cmd = add_pose_command(app);
    const auto join_cmd = add_join_command(app);
    const auto firmware_cmd = add_firmware_command(app);
    bool man_page = false;
    app.add_flag("--man-page", man_page, "print the manual page xlate5(1) (troff)")->group("");  // for the build

    try {
        app.parse(argc, argv);
    } catch (const CLI::Success& e) {
        return app.exit(e);
    } catch (const CLI::ParseError& e) {
        std::cerr << usage_error(app, e) << "\n";
        return kUsage;
    }

    if (man_page) {
        write_man_page(app, XLATE5_VERSION, std::cout);
        return kOk;
    }
    if (!translate.file.empty()) {
        // FILE is the translation's (in place): after a command, or a mistyped command name
        // that is no file, it is a word the parser could not place.
        std::vector<std::string> commands;
        bool any_command = false;
        for (const CLI::App* sub : app.get_subcommands([](const CLI::App*) { return true; })) {
            commands.push_back(sub->get_name());
            any_command = any_command || sub->parsed();
        }
        std::error_code ec;
        const std::string guess = std::filesystem::exists(translate.file, ec) ? std::string() : nearest(translate.file, commands);
        if (!guess.empty()) {
            std::cerr << "xlate5: unknown command '" << translate.file << "'; did you mean '" << guess << "'?\n(see 'xlate5 --help')\n";
            return kUsage;
        }
        if (any_command) {
            std::cerr << "xlate5: unexpected argument '" << translate.file << "'\n(see 'xlate5 --help')\n";
            return kUsage;
        }
    }
    if (machines_cmd->parsed()) return run_machines();
    if (const int code = run_serve_commands(*serve_cmds, common.machine); code >= 0) return code;
    if (const int code = run_calibrate_commands(*calibrate_cmds, common); code >= 0) return code;
    if (const int code = run_pose_command(*pose_cmd, common); code >= 0) return code;
    if (const int code = run_firmware_command(*firmware_cmd, common); code >= 0) return code;
    if (const int code = run_join_command(*join_cmd, common, translate); code >= 0) return code;
    return run_translate(common, translate);
}
