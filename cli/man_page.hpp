// SPDX-License-Identifier: GPL-3.0-or-later
// `xlate5 --man-page`: the manual page xlate5(1) in troff, written from the same command and
// option declarations that --help prints, so the two cannot drift (stage: command line; may
// read the CLI11 declarations only).
#pragma once
#include <CLI/CLI.hpp>
#include <ostream>
#include <string>

namespace xlate5::cli {

void write_man_page(const CLI::App& app, const std::string& version, std::ostream& out);

}  // namespace xlate5::cli
