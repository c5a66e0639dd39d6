// SPDX-License-Identifier: GPL-3.0-or-later
// Fuzz target: machine-file text -> Machine (TOML, parameters, expressions, chains, compensation)
// -> Kinematics, and for a machine that loads, forward and inverse kinematics at its home.
// Stage: test harness; may call the machine file reader and kinematics.
// Only MachineError may leave the reader; anything else thrown or any sanitizer report is a finding.
#include <cstddef>
#include <cstdint>
#include <string>

#include "translators/error.hpp"
#include "translators/kinematics/kinematics.hpp"
#include "translators/machine/machine.hpp"

using namespace xlate5;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::string text(reinterpret_cast<const char*>(data), size);
    try {
        const Machine m = load_machine_text(text, "fuzz.toml");
        const Kinematics kin(m);
        const auto home = m.home_joints();
        const Pose pose = kin.forward(home);
        std::vector<double> q;
        (void)kin.inverse(pose, home, q);
        std::vector<double> sent = home;
        if (m.compensation.apply(sent).empty()) m.compensation.undo(sent);
    } catch (const MachineError&) {
    }
    return 0;
}
