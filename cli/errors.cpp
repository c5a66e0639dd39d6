// SPDX-License-Identifier: GPL-3.0-or-later
// The command line's exit codes and error messages (stage: command line).
#include "cli/errors.hpp"

#include <CLI/CLI.hpp>
#include <cmath>
#include <cstdlib>
#include <iostream>

#include "translators/error.hpp"

namespace xlate5::cli {

int exit_with(std::exception_ptr error) {
    try {
        std::rethrow_exception(error);
    } catch (const InputError& e) {
        std::cerr << e.what() << "\n";
        return kInputError;
    } catch (const MachineError& e) {
        std::cerr << "xlate5: machine error: " << e.what() << "\n";
        return kMachineError;
    } catch (const IoError& e) {
        std::cerr << "xlate5: " << e.what() << "\n";
        return kIoError;
    } catch (const CLI::Error& e) {
        std::cerr << "xlate5: " << printable(e.what()) << "\n";  // an option's value is quoted
        return kUsage;
    } catch (const std::exception& e) {
        std::cerr << "xlate5: internal error: " << printable(e.what()) << "\n";
        return kInternal;
    }
}

std::map<std::string, double> parse_sets(const std::vector<std::string>& sets) {
    std::map<std::string, double> out;
    for (const auto& s : sets) {
        const auto eq = s.find('=');
        if (eq == std::string::npos || eq == 0) throw CLI::ValidationError("--set", "expected NAME=VALUE, got '" + s + "'");
        char* end = nullptr;
        const std::string value = s.substr(eq + 1);
        const double v = std::strtod(value.c_str(), &end);
        if (value.empty() || *end != '\0' || !std::isfinite(v))
            throw CLI::ValidationError("--set", "'" + value + "' is not a number in '" + s + "'");
        out[s.substr(0, eq)] = v;
    }
    return out;
}

}  // namespace xlate5::cli
