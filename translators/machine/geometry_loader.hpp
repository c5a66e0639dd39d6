// SPDX-License-Identifier: GPL-3.0-or-later
// The loader of [[bodies]] and [[collision]] (geometry.cpp), for machine_file.cpp only: it
// takes the parsed TOML, which no other header needs to see.
#pragma once
#include <map>
#include <string>
#include <toml++/toml.h>

#include "translators/machine/machine.hpp"

namespace xlate5 {

// Reads [[bodies]] and [collision] into m.geometry (left null when the file has no bodies).
// The chains must be loaded. `params` evaluate expressions. Throws MachineError naming the
// file, the line and the key. Meshes are read relative to the machine file's directory.
void load_geometry(const toml::table& root, const std::string& path, const std::map<std::string, double>& params,
                   Machine& m);

}  // namespace xlate5
