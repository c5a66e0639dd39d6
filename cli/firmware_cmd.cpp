// SPDX-License-Identifier: GPL-3.0-or-later
// `xlate5 firmware-config`: loads the machine and prints its firmware configuration lines
// (stage: command line).
#include "cli/firmware_cmd.hpp"

#include <cstdio>

#include "cli/options.hpp"
#include "translators/machine/firmware_config.hpp"
#include "translators/machine/machine.hpp"

namespace xlate5::cli {

std::unique_ptr<FirmwareCommand> add_firmware_command(CLI::App& app) {
    auto c = std::make_unique<FirmwareCommand>();
    c->command = app.add_subcommand("firmware-config",
                                    "print the firmware's side of the machine file: Marlin's Configuration.h axis lines, "
                                    "RepRapFirmware's M584/M208/M203, or Klipper's [manual_stepper] sections and the macro "
                                    "that registers them");
    c->command->add_option("--firmware", c->firmware, "the firmware to configure")
        ->required()
        ->check(CLI::IsMember({"marlin", "reprap", "klipper"}))
        ->option_text("marlin|reprap|klipper");
    return c;
}

int run_firmware_command(const FirmwareCommand& c, const Common& common) {
    if (!c.command->parsed()) return -1;
    try {
        if (common.machine.empty()) throw CLI::ValidationError("--machine", "firmware-config needs the machine (see 'xlate5 machines')");
        const Machine machine = load_machine(common.machine, parse_sets(common.sets));
        const FirmwareKind kind = c.firmware == "marlin" ? FirmwareKind::Marlin
                                  : c.firmware == "reprap" ? FirmwareKind::RepRap
                                                           : FirmwareKind::Klipper;
        const std::string text = firmware_config(machine, kind);
        std::fwrite(text.data(), 1, text.size(), stdout);
        return std::fflush(stdout) == 0 ? kOk : kIoError;
    } catch (...) {
        return exit_with(std::current_exception());
    }
}

}  // namespace xlate5::cli
