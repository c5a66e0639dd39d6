// `xlate5 serve` and `xlate5 ports`: the configuration file, then the flags over it, handed to
// the service (stage: command line).
#include "cli/serve_cmd.hpp"

#include <iostream>

#include "cli/errors.hpp"
#include "daemon/serve.hpp"
#include "translators/error.hpp"

namespace xlate5::cli {

std::unique_ptr<ServeCommands> add_serve_commands(CLI::App& app) {
    auto c = std::make_unique<ServeCommands>();
    auto* s = app.add_subcommand("serve", "be the printer for a sender: translate its lines and drive the firmware over serial");
    c->serve = s;
    s->add_option("-c,--config", c->config, "service configuration (TOML; see config/xlate5.toml); flags override it");
    s->add_option("--port", c->port, "the firmware's serial device (see 'xlate5 ports'), or 'sim'");
    s->add_option("--printer", c->printer, "'sim': the built-in virtual printer instead of a serial port")->check(CLI::IsMember({"sim", "serial"}));
    s->add_option("--baud", c->baud, "the firmware's baud rate (default 115200)")->check(CLI::PositiveNumber);
    s->add_option("--flavor", c->flavor, "the firmware: marlin or reprap")->check(CLI::IsMember({"marlin", "reprap"}));
    s->add_option("--pty", c->pty, "path of the symlink to the pseudo-terminal senders open (default /run/xlate5/printer)");
    s->add_option("--pty-group", c->pty_group, "give the pseudo-terminal to this group, read-write (e.g. dialout, for OctoPrint)");
    s->add_flag("--no-pty", c->no_pty, "no pseudo-terminal endpoint (TCP only)");
    s->add_option("--tcp", c->tcp, "also accept senders on HOST:PORT (loopback unless --allow-remote)");
    s->add_flag("--allow-remote", c->allow_remote, "allow --tcp on an address other than loopback");
    s->add_option("--drain-timeout", c->drain_timeout, "seconds SIGTERM waits for the queue to drain");
    s->add_option("--reply-timeout", c->reply_timeout, "seconds without a firmware reply before the oldest line is sent again");
    s->add_option("--boot-wait", c->boot_wait, "seconds to wait for the firmware's 'start' after opening the port");
    s->add_option("--record", c->record, "virtual printer: write every executed command to this file");
    s->add_option("--sim-flavor", c->sim_flavor, "virtual printer personality: marlin or reprap")->check(CLI::IsMember({"marlin", "reprap"}));
    s->add_option("--sim-baud", c->sim_baud, "virtual printer: the link's speed (0: unlimited)");
    s->add_flag("--sim-advanced-ok", c->advanced_ok, "virtual printer: Marlin's ADVANCED_OK");
    s->add_option("--sim-fault", c->faults, "virtual printer fault, NAME=VALUE (corrupt, drop, garble_reply, spurious_resend, "
                                            "no_ok_after_resend, busy, busy_seconds, move_ms, reset_after, kill_after, unplug_after, seed)");
    s->add_option("--log-level", c->log_level, "trace, debug, info, warn, error")->check(CLI::IsMember({"trace", "debug", "info", "warn", "error"}));
    c->ports = app.add_subcommand("ports", "list serial ports (USB vendor:product and description)");
    return c;
}

int run_serve_commands(const ServeCommands& c, const std::string& machine) {
    if (c.ports->parsed()) return run_ports();
    if (!c.serve->parsed()) return -1;
    ServeConfig cfg;
    try {
        if (!c.config.empty()) cfg = load_serve_config(c.config);
        if (!machine.empty()) cfg.machine = machine;
        if (!c.port.empty()) cfg.port = c.port;
        if (c.printer == "sim") cfg.port = "sim";
        if (c.printer == "serial" && cfg.port == "sim") throw CLI::ValidationError("--printer", "serial needs --port DEVICE");
        if (c.baud) cfg.baud = c.baud;
        if (!c.flavor.empty()) cfg.firmware.reprap = c.flavor == "reprap";
        if (!c.pty.empty()) cfg.pty = c.pty;
        if (!c.pty_group.empty()) cfg.pty_group = c.pty_group;
        if (c.no_pty) cfg.pty.clear();
        if (!c.tcp.empty()) cfg.tcp = c.tcp;
        if (c.allow_remote) cfg.allow_remote = true;
        if (c.drain_timeout >= 0) cfg.drain_timeout = c.drain_timeout;
        if (c.reply_timeout > 0) cfg.firmware.reply_timeout = c.reply_timeout;
        if (c.boot_wait >= 0) cfg.firmware.boot_wait = c.boot_wait;
        if (!c.record.empty()) cfg.sim.record_path = c.record;
        if (!c.sim_flavor.empty()) cfg.sim.reprap = c.sim_flavor == "reprap";
        if (c.sim_baud >= 0) cfg.sim.baud = c.sim_baud;
        if (c.advanced_ok) cfg.sim.advanced_ok = true;
        for (const auto& f : c.faults) {
            try {
                set_sim_fault(cfg.sim.faults, f);
            } catch (const std::invalid_argument& e) {
                throw CLI::ValidationError("--sim-fault", e.what());
            }
        }
        if (!c.log_level.empty()) cfg.log_level = c.log_level;
        if (cfg.pty.empty() && cfg.tcp.empty()) throw CLI::ValidationError("--no-pty", "no sender endpoint left: give --tcp");
    } catch (const MachineError& e) {
        std::cerr << "xlate5: configuration error: " << e.what() << "\n";
        return kMachineError;
    } catch (const CLI::Error& e) {
        std::cerr << "xlate5: " << e.what() << "\n";
        return kUsage;
    }
    return run_serve(cfg);
}

}  // namespace xlate5::cli
