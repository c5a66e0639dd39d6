// SPDX-License-Identifier: GPL-3.0-or-later
// `xlate5 serve` and `xlate5 ports`: flags that override the service's configuration file
// (stage: command line; may call daemon/serve and daemon/config, the service's front door).
#pragma once
#include <CLI/CLI.hpp>
#include <map>
#include <memory>
#include <string>
#include <vector>

namespace xlate5::cli {

struct ServeCommands {
    CLI::App* serve = nullptr;
    CLI::App* ports = nullptr;
    std::string config, printer, check;
    bool no_pty = false;
    std::vector<std::string> faults;
    // One flag per configuration key (daemon/config's table), by key: the text given, or the switch.
    std::map<std::string, std::string> values;
    std::map<std::string, bool> switches;
    std::map<std::string, CLI::Option*> given;
};

std::unique_ptr<ServeCommands> add_serve_commands(CLI::App& app);
// The exit code when one of the two ran, -1 when neither was asked for.
int run_serve_commands(const ServeCommands& c, const std::string& machine);

}  // namespace xlate5::cli
