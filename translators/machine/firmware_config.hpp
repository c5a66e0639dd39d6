// SPDX-License-Identifier: GPL-3.0-or-later
// The firmware's side of a machine file (`xlate5 firmware-config`): the axis lines of Marlin's
// Configuration.h, RepRapFirmware's M584/M208/M203 (and M92's place), Klipper's
// [manual_stepper] sections and the macro that registers them as G-code axes, written from the
// machine file so the two cannot disagree. Only what the machine file knows: driver numbers,
// pins and steps per unit are the user's, and the text says so where they go.
// May call: the machine data.
#pragma once
#include <string>

#include "translators/machine/machine.hpp"

namespace xlate5 {

enum class FirmwareKind { Marlin, RepRap, Klipper };

// Throws MachineError when the machine's letters cannot be that firmware's (Marlin names its
// extra axes from A B C U V W in that order; its linear axes must be X Y Z).
std::string firmware_config(const Machine& machine, FirmwareKind kind);

// The lines every output for this machine starts with, after xlate5's header: for the Klipper
// dialect, the registration of each extra axis (MANUAL_STEPPER ... GCODE_AXIS=), without which
// Klipper drops those words silently. Empty for the other dialects.
std::string firmware_preamble(const Machine& machine);

// Klipper's registration of joint j as its G-code axis, one line with its '\n'.
std::string klipper_register(const Joint& joint);

}  // namespace xlate5
