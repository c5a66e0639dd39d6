// SPDX-License-Identifier: GPL-3.0-or-later
// `xlate5 machines`: each machine file's name and description (stage: command line).
#include "cli/machines_cmd.hpp"

#include <cstdio>
#include <iostream>

#include "cli/errors.hpp"
#include "translators/error.hpp"
#include "translators/machine/machine.hpp"

namespace xlate5::cli {

int run_machines() {
    const auto machines = bundled_machines();
    if (machines.empty()) {
        std::cerr << "xlate5: no machine files found (searched:";
        for (const auto& d : machine_search_path()) std::cerr << " " << d;
        std::cerr << ")\n";
        return kMachineError;
    }
    for (const auto& [name, path] : machines) {
        try {
            const auto m = load_machine(path);
            std::printf("%-12s %s\n", name.c_str(), m.description.c_str());
        } catch (const MachineError& e) {
            std::printf("%-12s (broken: %s)\n", name.c_str(), e.what());
        }
    }
    return kOk;
}

}  // namespace xlate5::cli
