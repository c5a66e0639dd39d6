// SPDX-License-Identifier: GPL-3.0-or-later
// `xlate5 --machine M firmware-config --firmware marlin|reprap|klipper`: the firmware's side of
// the machine file (axis letters, limits, speeds, Klipper's manual steppers and their
// registration), printed so the two cannot disagree (stage: command line; may call the machine
// file reader and translators/firmware_config).
#pragma once
#include <CLI/CLI.hpp>
#include <memory>
#include <string>

#include "cli/errors.hpp"

namespace xlate5::cli {

struct FirmwareCommand {
    CLI::App* command = nullptr;
    std::string firmware;
};

std::unique_ptr<FirmwareCommand> add_firmware_command(CLI::App& app);
// The exit code when `firmware-config` ran, -1 when it was not asked for.
int run_firmware_command(const FirmwareCommand& c, const Common& common);

}  // namespace xlate5::cli
