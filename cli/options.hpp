// SPDX-License-Identifier: GPL-3.0-or-later
// Pieces every command's declarations share: readable bounds for numbers, defaults in the help
// text, and the nearest known name for a mistyped one (stage: command line; may call CLI11).
#pragma once
#include <CLI/CLI.hpp>
#include <string>
#include <vector>

namespace xlate5::cli {

// A finite number within [lo, hi] ((lo, hi] with above_lo), named in errors as e.g.
// "a number above 0 and at most 10 (mm)". The bounds are part of the help text.
CLI::Validator number_in(double lo, double hi, const std::string& unit, bool above_lo = false);
// A whole number within [lo, hi].
CLI::Validator whole_in(long long lo, long long hi, const std::string& unit);

// "what it does (default: value)": how the help shows a default.
std::string with_default(const std::string& description, const std::string& value);
std::string number_text(double v);

// The known name nearest to `typed` by edit distance (a swap of two neighbours counts one), if
// it is near enough to be a typo: at most a third of the longer name's letters, at least 1.
std::string nearest(const std::string& typed, const std::vector<std::string>& known);

// The message for a command line CLI11 refused, starting "xlate5: ", with the nearest option or
// command for a mistyped one, and where to find the help.
std::string usage_error(const CLI::App& app, const CLI::ParseError& e);

}  // namespace xlate5::cli
