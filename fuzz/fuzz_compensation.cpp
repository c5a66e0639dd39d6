// SPDX-License-Identifier: GPL-3.0-or-later
// Fuzz target: a compensation file (the [[compensation]] terms of `translate --compensation`) for
// each bundled machine, then the terms applied and undone over a sweep of the rotaries.
// Stage: test harness; may call the machine file reader and the compensation tables.
// Input: byte 0 picks the machine, the rest is the file. Only MachineError may leave the reader.
#include <cstddef>
#include <cstdint>
#include <string>

#include "fuzz/fuzz_common.hpp"
#include "translators/error.hpp"
#include "translators/machine/machine.hpp"

using namespace xlate5;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    if (size < 1) return 0;
    const auto& machines = fuzz::bundled();
    Machine m = machines[data[0] % machines.size()];
    try {
        load_compensation_file(fuzz::as_file(data + 1, size - 1), m);
    } catch (const MachineError&) {
        return 0;
    }
    // Through the table ends, the wrap and far outside them.
    for (double angle : {-1e6, -720.0, -360.0, -180.0, -0.5, 0.0, 0.5, 90.0, 180.0, 359.9, 360.0, 1e6}) {
        std::vector<double> q = m.home_joints();
        for (std::size_t i = 0; i < q.size(); ++i)
            if (m.joints[i].rotary) q[i] = angle;
        if (m.compensation.apply(q).empty()) m.compensation.undo(q);
    }
    return 0;
}
