// SPDX-License-Identifier: GPL-3.0-or-later
// `xlate5 serve` and `xlate5 ports`: the configuration file, then the flags over it, handed to
// the service (stage: command line; may call daemon/serve and daemon/config). Every flag is a row
// of the configuration's settings table, so the file and the flags share one set of bounds.
#include "cli/serve_cmd.hpp"

#include <iostream>

#include "cli/errors.hpp"
#include "cli/options.hpp"
#include "daemon/serve.hpp"
#include "translators/error.hpp"

namespace xlate5::cli {
namespace {

using Kind = ServeSetting::Kind;

// How the help shows a default that is not simply a value.
std::string default_text(const ServeConfig& d, const ServeSetting& s) {
    const std::string k = s.key, v = serve_setting_text(d, s);
    if (k == "machine") return "none: required unless --config gives one";
    if (k == "firmware.port") return "none: required unless --printer sim or --config gives one";
    if (k == "compensation") return "the machine file's";
    if (k == "tolerance") return "0, the machine file's";
    if (k == "mode") return "the machine file's [input] mode";
    if (k == "firmware.window") return "0: 2, or learned from ADVANCED_OK";
    if (k == "sender.pty_group") return "the service's own";
    if (k == "sim.baud" && v == "0") return "0, unlimited";
    if (s.kind == Kind::Switch) return v == "true" ? "on" : "off";
    return v.empty() ? "none" : v;
}

std::string metavar(const ServeSetting& s) {
    const std::string k = s.key;
    if (k == "machine") return "NAME|PATH";
    if (k == "firmware.port") return "DEVICE";
    if (k == "sender.pty_group") return "GROUP";
    if (k == "sender.tcp" || k == "http") return "HOST:PORT";
    if (k == "extruder_letter") return "LETTER";
    if (k == "sender.pty") return "PATH";
    return "FILE";
}

std::vector<std::string> choices_of(const ServeSetting& s) {
    std::vector<std::string> out;
    std::string c = s.choices;
    for (std::size_t at = 0;;) {
        const auto bar = c.find('|', at);
        out.push_back(c.substr(at, bar == std::string::npos ? std::string::npos : bar - at));
        if (bar == std::string::npos) return out;
        at = bar + 1;
    }
}

}  // namespace

std::unique_ptr<ServeCommands> add_serve_commands(CLI::App& app) {
    auto c = std::make_unique<ServeCommands>();
    // The defaults shown are the service's own (a configuration without the key, no flag), read
    // from ServeConfig so the help cannot drift from what runs; the bounds are the settings
    // table's, the same the configuration file is checked against.
    const ServeConfig d;
    auto* s = app.add_subcommand("serve", "be the printer for a sender: translate its lines and drive the firmware over serial");
    c->serve = s;
    s->add_option("-c,--config", c->config, with_default("service configuration (TOML; see xlate5.toml.example); flags override it", "none"))
        ->option_text("FILE");
    s->add_option("--check", c->check,
                  with_default("start nothing: tell what serve would do with this G-code file that offline translation does not "
                               "(where it releases held output, where it would cancel), and the link settings it would use; "
                               "exit 0 when serve prints it exactly as offline, 1 when not",
                               "off"))
        ->option_text("GCODE");
    s->add_option("--printer", c->printer, with_default("'sim': the built-in virtual printer instead of a serial port", "serial"))
        ->check(CLI::IsMember({"sim", "serial"}))
        ->option_text("sim|serial");
    s->add_flag("--no-pty", c->no_pty, with_default("no pseudo-terminal endpoint (TCP only)", "off"));
    for (const auto& row : serve_settings()) {
        const std::string help = std::string(row.help) + " [" + row.key + "]";
        CLI::Option* o = nullptr;
        if (row.kind == Kind::Switch) {
            o = s->add_flag(row.names, c->switches[row.key], with_default(help, default_text(d, row)));
        } else {
            o = s->add_option(row.names, c->values[row.key], with_default(help, default_text(d, row)));
            if (row.kind == Kind::Number) o->check(number_in(row.lo, row.hi, row.unit))->option_text("N");
            else if (row.kind == Kind::Whole)
                o->check(whole_in(static_cast<long long>(row.lo), static_cast<long long>(row.hi), row.unit))->option_text("N");
            else if (row.kind == Kind::Choice) o->check(CLI::IsMember(choices_of(row)))->option_text(row.choices);
            else o->option_text(metavar(row));
        }
        o->multi_option_policy(CLI::MultiOptionPolicy::TakeLast);  // a later flag overrides an earlier one
        c->given[row.key] = o;
    }
    s->add_option("--sim-fault", c->faults,
                  with_default("virtual printer fault, NAME=VALUE, repeatable (corrupt, drop, lose_newline, lose_ok, garble_reply, "
                               "spurious_resend, no_ok_after_resend, greeting_resend, stale_oks, quiet_planner, busy, busy_seconds, "
                               "move_ms, slow_seconds, reset_after, reset_every, kill_after, stop_after, unplug_after, seed)",
                               "none"))
        ->option_text("NAME=VALUE");
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
        for (const auto& row : serve_settings()) {
            const CLI::Option* o = c.given.at(row.key);
            if (!o || o->count() == 0) continue;
            try {
                apply_serve_setting(cfg, row, row.kind == Kind::Switch ? (c.switches.at(row.key) ? "true" : "false") : c.values.at(row.key));
            } catch (const SettingError& e) {
                throw CLI::ValidationError(o->get_name(), e.what());
            }
        }
        if (c.printer == "sim") cfg.port = "sim";
        if (c.printer == "serial" && cfg.port == "sim") throw CLI::ValidationError("--printer", "serial needs --port DEVICE");
        if (c.no_pty) cfg.pty.clear();
        for (const auto& f : c.faults) {
            try {
                set_sim_fault(cfg.sim.faults, f);
            } catch (const std::invalid_argument& e) {
                throw CLI::ValidationError("--sim-fault", e.what());
            }
        }
        // The machine decides every joint move: like the port, it is asked for, never assumed.
        const auto require_machine = [&] {
            if (cfg.machine.empty())
                throw CLI::ValidationError("serve", "needs the machine: --machine NAME|PATH (see 'xlate5 machines') or machine = \"NAME\" "
                                                    "in --config FILE");
        };
        if (!c.check.empty()) {
            require_machine();
            return run_serve_check(cfg, c.check);
        }
        // A service that silently drives its simulator when the port was forgotten would look
        // like a working printer: the port (or the simulator) must be asked for.
        if (cfg.port.empty())
            throw CLI::ValidationError("serve", "needs the printer's port: --port DEVICE (see 'xlate5 ports'), --printer sim for the "
                                                "built-in virtual printer, or [firmware] port in --config FILE");
        require_machine();
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
