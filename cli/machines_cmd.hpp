// SPDX-License-Identifier: GPL-3.0-or-later
// `xlate5 machines`: the machine files found on the search path (stage: command line; may call
// the machine file reader).
#pragma once

namespace xlate5::cli {

int run_machines();

}  // namespace xlate5::cli
