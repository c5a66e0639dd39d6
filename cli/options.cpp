// SPDX-License-Identifier: GPL-3.0-or-later
// Readable bounds, defaults and typo suggestions for the command line (stage: command line).
#include "cli/options.hpp"

#include "translators/suggest.hpp"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>

namespace xlate5::cli {

std::string number_text(double v) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%g", v);
    return buf;
}

namespace {

std::string unit_suffix(const std::string& unit) { return unit.empty() ? "" : " (" + unit + ")"; }

}  // namespace

CLI::Validator number_in(double lo, double hi, const std::string& unit, bool above_lo) {
    const std::string range = (above_lo ? "above " : "from ") + number_text(lo) + (above_lo ? " and at most " : " to ") + number_text(hi);
    return CLI::Validator(
        [lo, hi, above_lo, range, unit](std::string& input) -> std::string {
            errno = 0;
            char* end = nullptr;
            const double v = std::strtod(input.c_str(), &end);
            const bool number = !input.empty() && end && *end == '\0' && errno != ERANGE && std::isfinite(v);
            if (number && (above_lo ? v > lo : v >= lo) && v <= hi) return {};
            return "'" + input + "' is not a number " + range + unit_suffix(unit);
        },
        range + unit_suffix(unit));
}

CLI::Validator whole_in(long long lo, long long hi, const std::string& unit) {
    const std::string range = "from " + std::to_string(lo) + " to " + std::to_string(hi);
    return CLI::Validator(
        [lo, hi, range, unit](std::string& input) -> std::string {
            errno = 0;
            char* end = nullptr;
            const long long v = std::strtoll(input.c_str(), &end, 10);
            if (!input.empty() && end && *end == '\0' && errno != ERANGE && v >= lo && v <= hi) return {};
            return "'" + input + "' is not a whole number " + range + unit_suffix(unit);
        },
        range + unit_suffix(unit));
}

std::string with_default(const std::string& description, const std::string& value) {
    return description + " (default: " + value + ")";
}

std::string nearest(const std::string& typed, const std::vector<std::string>& known) { return nearest_name(typed, known); }

namespace {

// The names a user could have meant at this point: the options and commands of the program and
// of each command given so far (their options fall through to the program's).
// The innermost command's options come first, so they win a tie (serve's --port over --plot).
void names_in_scope(const CLI::App& app, std::vector<std::string>& options, std::vector<std::string>& commands, std::string& help) {
    std::vector<std::string> own;
    for (const CLI::Option* o : app.get_options()) {
        for (const auto& l : o->get_lnames()) own.push_back("--" + l);
        for (const auto& s : o->get_snames()) own.push_back("-" + s);
    }
    options.insert(options.begin(), own.begin(), own.end());
    for (const CLI::App* sub : app.get_subcommands([](const CLI::App*) { return true; })) commands.push_back(sub->get_name());
    for (const CLI::App* sub : app.get_subcommands([](const CLI::App* s) { return s->parsed(); })) {
        commands.clear();  // a command given: only its own subcommands can follow
        help += " " + sub->get_name();
        names_in_scope(*sub, options, commands, help);
    }
}

}  // namespace

std::string usage_error(const CLI::App& app, const CLI::ParseError& e) {
    std::vector<std::string> options, commands;
    std::string help = "xlate5";
    names_in_scope(app, options, commands, help);
    const std::string hint = "\n(see '" + help + " --help')";
    // Words CLI11 could not place, whatever it then refused: a mistyped name is the likely cause.
    const std::vector<std::string> extras = app.remaining(true);
    const auto is_option = [](const std::string& w) {
        return w.size() >= 2 && w[0] == '-' && !std::isdigit(static_cast<unsigned char>(w[1])) && w[1] != '.';
    };
    // A mistyped command first: the options after it are unknown only because of it. The
    // translation's FILE may have taken it.
    std::vector<std::string> words = extras;
    if (const CLI::Option* file = app.get_option_no_throw("file"); file && file->count() > 0)
        words.insert(words.begin(), file->results().begin(), file->results().end());
    for (const auto& word : words) {
        if (is_option(word)) continue;
        if (const std::string guess = nearest(word, commands); !guess.empty())
            return "xlate5: unknown command '" + word + "'; did you mean '" + guess + "'?" + hint;
    }
    // Then the first unknown option (the words after it are most likely its value).
    for (const auto& word : extras) {
        if (!is_option(word)) continue;
        const std::string name = word.substr(0, word.find('='));
        const std::string guess = nearest(name, options);
        return "xlate5: unknown option '" + name + "'" + (guess.empty() ? "" : "; did you mean '" + guess + "'?") + hint;
    }
    if (dynamic_cast<const CLI::ExtrasError*>(&e) && !extras.empty()) {
        std::string words;
        for (const auto& w : extras) words += (words.empty() ? "'" : " '") + w + "'";
        return "xlate5: unexpected argument" + std::string(extras.size() > 1 ? "s " : " ") + words + hint;
    }
    return "xlate5: " + std::string(e.what()) + hint;
}

}  // namespace xlate5::cli
