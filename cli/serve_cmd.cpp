// `xlate5 serve` and `xlate5 ports`: the configuration file, then the flags over it, handed to
// the service (stage: command line).
#include "cli/serve_cmd.hpp"

#include <iostream>

#include "cli/errors.hpp"
#include "cli/options.hpp"
#include "daemon/serve.hpp"
#include "translators/error.hpp"

namespace xlate5::cli {

std::unique_ptr<ServeCommands> add_serve_commands(CLI::App& app) {
    auto c = std::make_unique<ServeCommands>();
    // The defaults shown are the service's own (a configuration without the key, no flag), read
    // from ServeConfig so the help cannot drift from what runs. The bounds are the configuration
    // file's (daemon/config.cpp).
    const ServeConfig d;
    const auto flavor = [](bool reprap) { return std::string(reprap ? "reprap" : "marlin"); };
    auto* s = app.add_subcommand("serve", "be the printer for a sender: translate its lines and drive the firmware over serial");
    c->serve = s;
    s->add_option("-c,--config", c->config, with_default("service configuration (TOML; see xlate5.toml.example); flags override it", "none"))
        ->option_text("FILE");
    s->add_option("-m,--machine", c->machine, with_default("machine name (see 'xlate5 machines') or path to a machine .toml", d.machine))
        ->option_text("NAME|PATH");
    s->add_option("--port", c->port, with_default("the firmware's serial device (see 'xlate5 ports'), or 'sim'",
                                                  "none: required unless --printer sim or --config gives one"))
        ->option_text("DEVICE");
    s->add_option("--printer", c->printer, with_default("'sim': the built-in virtual printer instead of a serial port", "serial"))
        ->check(CLI::IsMember({"sim", "serial"}))
        ->option_text("sim|serial");
    s->add_option("--baud", c->baud, with_default("the firmware's baud rate", std::to_string(d.baud)))
        ->check(whole_in(300, 4000000, ""))
        ->option_text("N");
    s->add_option("--flavor", c->flavor, with_default("the firmware", flavor(d.firmware.reprap)))
        ->check(CLI::IsMember({"marlin", "reprap"}))
        ->option_text("marlin|reprap");
    s->add_option("--pty", c->pty, with_default("path of the symlink to the pseudo-terminal senders open", d.pty))->option_text("PATH");
    s->add_option("--pty-group", c->pty_group, with_default("give the pseudo-terminal to this group, read-write (e.g. dialout, for OctoPrint)",
                                                            d.pty_group.empty() ? "the service's own" : d.pty_group))
        ->option_text("GROUP");
    s->add_flag("--no-pty", c->no_pty, with_default("no pseudo-terminal endpoint (TCP only)", "off"));
    s->add_option("--tcp", c->tcp, with_default("also accept senders on HOST:PORT (loopback unless --allow-remote)", d.tcp.empty() ? "none" : d.tcp))
        ->option_text("HOST:PORT");
    s->add_flag("--allow-remote", c->allow_remote, with_default("allow --tcp on an address other than loopback", d.allow_remote ? "on" : "off"));
    s->add_option("--drain-timeout", c->drain_timeout, with_default("seconds SIGTERM waits for the queue to drain", number_text(d.drain_timeout)))
        ->check(number_in(0, 86400, "s"))
        ->option_text("S");
    s->add_option("--reply-timeout", c->reply_timeout,
                  with_default("seconds without a firmware reply before the oldest line is sent again", number_text(d.firmware.reply_timeout)))
        ->check(number_in(0.05, 600, "s"))
        ->option_text("S");
    s->add_option("--boot-wait", c->boot_wait,
                  with_default("seconds to wait for the firmware's 'start' after opening the port", number_text(d.firmware.boot_wait)))
        ->check(number_in(0, 60, "s"))
        ->option_text("S");
    s->add_option("--record", c->record, with_default("virtual printer: write every executed command to this file", "none"))->option_text("FILE");
    s->add_option("--sim-flavor", c->sim_flavor, with_default("virtual printer personality", flavor(d.sim.reprap)))
        ->check(CLI::IsMember({"marlin", "reprap"}))
        ->option_text("marlin|reprap");
    s->add_option("--sim-baud", c->sim_baud,
                  with_default("virtual printer: the link's speed, 0 for unlimited", d.sim.baud ? std::to_string(d.sim.baud) : "0, unlimited"))
        ->check(whole_in(0, 4000000, ""))
        ->option_text("N");
    s->add_flag("--sim-advanced-ok", c->advanced_ok, with_default("virtual printer: Marlin's ADVANCED_OK", d.sim.advanced_ok ? "on" : "off"));
    s->add_option("--sim-fault", c->faults,
                  with_default("virtual printer fault, NAME=VALUE, repeatable (corrupt, drop, garble_reply, spurious_resend, "
                               "no_ok_after_resend, busy, busy_seconds, move_ms, reset_after, kill_after, unplug_after, seed)",
                               "none"))
        ->option_text("NAME=VALUE");
    s->add_option("--log-level", c->log_level, with_default("how much the service logs", d.log_level))
        ->check(CLI::IsMember({"trace", "debug", "info", "warn", "error"}))
        ->option_text("trace|debug|info|warn|error");
    c->ports = app.add_subcommand("ports", "list serial ports (USB vendor:product and description)");
    return c;
}

int run_serve_commands(const ServeCommands& c, const std::string& machine) {
    if (c.ports->parsed()) return run_ports();
    if (!c.serve->parsed()) return -1;
    ServeConfig cfg;
    try {
        // A service that silently drives its simulator when the port was forgotten would look
        // like a working printer: the port (or the simulator) must be asked for.
        if (c.config.empty() && c.port.empty() && c.printer != "sim")
            throw CLI::ValidationError("serve", "needs the printer's port: --port DEVICE (see 'xlate5 ports'), "
                                                "--printer sim for the built-in virtual printer, or --config FILE");
        if (!c.config.empty()) cfg = load_serve_config(c.config);
        if (!c.machine.empty()) cfg.machine = c.machine;
        else if (!machine.empty()) cfg.machine = machine;
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
