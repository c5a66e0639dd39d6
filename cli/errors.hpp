// SPDX-License-Identifier: GPL-3.0-or-later
// The command line's exit codes and how every error ends (stage: command line; may call the
// translators' error types and CLI11). Documented in the README; scripts rely on them.
#pragma once
#include <exception>
#include <map>
#include <string>
#include <vector>

namespace xlate5::cli {

enum Exit : int {
    kOk = 0,
    kInputError = 1,    // the G-code cannot be translated (file:line:column: message)
    kUsage = 2,         // bad command line
    kMachineError = 3,  // machine file missing or broken, or a --set that does not apply
    kIoError = 4,       // cannot read the input or write the output
    kInternal = 70,
};

// Prints the error's message on standard error and returns its documented exit code.
int exit_with(std::exception_ptr error);

// --set NAME=VALUE ... as a map; throws CLI::ValidationError on a malformed one.
std::map<std::string, double> parse_sets(const std::vector<std::string>& sets);

// The options every command shares (they may come before or after the subcommand).
struct Common {
    std::string machine;
    std::vector<std::string> sets;
};

}  // namespace xlate5::cli
