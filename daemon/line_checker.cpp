// SPDX-License-Identifier: GPL-3.0-or-later
#include "daemon/line_checker.hpp"

#include <cstdlib>

namespace xlate5::proto {
namespace {

// Marlin compares strtol(text after the last '*') with the XOR of everything before it:
// digits are read up to the first non-digit, so "*117N79 G1 X1" (a joined line) reads 117.
bool marlin_checksum_ok(std::string_view line) {
    while (!line.empty() && (line.front() == ' ' || line.front() == '\t')) line.remove_prefix(1);
    const auto semicolon = line.find(';');
    const auto star = line.substr(0, semicolon).rfind('*');
    if (star == std::string_view::npos) return false;
    const std::string digits(line.substr(star + 1, 12));
    return std::strtol(digits.c_str(), nullptr, 10) == long(checksum(line.substr(0, star)));
}

}  // namespace

LineChecker::Result LineChecker::check(std::string_view line) {
    const auto r = parse_received(line);
    Result out;
    out.number = r.number;
    out.command = r.command;
    if (r.bad_number) {
        // Marlin reads any line that starts with N as numbered (strtol of what follows): a
        // damaged number is refused, never run as a command "N".
        out.verdict = Verdict::Refuse;
        out.why = kErrLineNumber;
        return out;
    }
    if (!r.number) {
        if (r.has_checksum && strict_unnumbered_) {
            out.verdict = Verdict::Refuse;
            out.why = kErrNoLineNumber;
        }
        return out;
    }
    // Marlin reads the number first: M110's own N word, when it has one, is the number checked.
    const auto code = command_code(strip_comment(r.command));
    const bool m110 = code.is('M', 110);
    std::int64_t n = *r.number;
    if (m110)
        if (const auto set = m110_line(strip_comment(r.command))) n = *set;
    if (n < -kMaxLineNumber || n > kMaxLineNumber) {
        out.verdict = Verdict::Refuse;
        out.why = kErrLineNumber;
        return out;
    }
    if (!m110 && n != last_n_ + 1) {
        if (n == last_n_ || n == last_n_ - 1) {
            out.verdict = Verdict::Duplicate;
        } else {
            out.verdict = Verdict::Refuse;
            out.why = kErrLineNumber;
        }
        return out;
    }
    if (!r.has_checksum) {
        out.verdict = Verdict::Refuse;
        out.why = kErrNoChecksum;
        return out;
    }
    if (!r.checksum_ok && !marlin_checksum_ok(line)) {
        out.verdict = Verdict::Refuse;
        out.why = kErrChecksumMismatch;
        return out;
    }
    last_n_ = n;
    return out;
}

std::string LineChecker::error_line(std::string_view why) const {
    return "Error:" + std::string(why) + ", Last Line: " + std::to_string(last_n_);
}

std::string LineChecker::resend_line() const { return "Resend: " + std::to_string(last_n_ + 1); }

}  // namespace xlate5::proto
