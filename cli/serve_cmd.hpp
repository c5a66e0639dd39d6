// `xlate5 serve` and `xlate5 ports`: flags that override the service's configuration file
// (stage: command line; may call daemon/serve and daemon/config, the service's front door).
#pragma once
#include <CLI/CLI.hpp>
#include <memory>
#include <string>
#include <vector>

namespace xlate5::cli {

struct ServeCommands {
    CLI::App* serve = nullptr;
    CLI::App* ports = nullptr;
    std::string config, machine, port, printer, flavor, pty, pty_group, tcp, record, sim_flavor, log_level;
    int baud = 0, sim_baud = -1;
    bool allow_remote = false, advanced_ok = false, no_pty = false;
    double drain_timeout = -1, reply_timeout = 0, boot_wait = -1;
    std::vector<std::string> faults;
};

std::unique_ptr<ServeCommands> add_serve_commands(CLI::App& app);
// The exit code when one of the two ran, -1 when neither was asked for.
int run_serve_commands(const ServeCommands& c, const std::string& machine);

}  // namespace xlate5::cli
