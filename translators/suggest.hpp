// SPDX-License-Identifier: GPL-3.0-or-later
// "Did you mean …?": the nearest known name to a mistyped one (options, commands, machine
// names, machine-file keys, parameters). Stage: shared helpers; calls the standard library only.
#pragma once
#include <string>
#include <vector>

namespace xlate5 {

// The known name nearest to `typed` by edit distance (a swap of two neighbours counts one), if
// it is near enough to be a typo: at most a third of the longer name's letters (leading dashes
// of an option not counted), at least 1. Empty when none is.
std::string nearest_name(const std::string& typed, const std::vector<std::string>& known);

}  // namespace xlate5
