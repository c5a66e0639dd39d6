// SPDX-License-Identifier: GPL-3.0-or-later
// Shared by the fuzz targets (stage: test harness; may call the machine file reader).
#pragma once
#include <string>
#include <vector>

#include "translators/machine/machine.hpp"

namespace xlate5::fuzz {

// The bundled machines (machines/*.toml of the source tree), loaded once, sorted by file name so
// that a byte of the input names the same machine in every run.
const std::vector<Machine>& bundled();

// An in-memory file (memfd) holding `data`, for the readers that take a path; the path stays
// valid until the next call.
const std::string& as_file(const std::uint8_t* data, std::size_t size);

}  // namespace xlate5::fuzz
