// SPDX-License-Identifier: GPL-3.0-or-later
// The printer's side of the host line protocol: how a received line is judged before it is
// queued (Marlin's get_serial_commands rules, see docs/service.md, "Marlin's receive
// rules"): line number first, then checksum; M110 sets the number. Pure; shared by the sender
// session (xlate5 as the printer) and the virtual printer (a test double of Marlin), so both
// refuse with the same words. May call line_protocol only.
#pragma once
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "daemon/line_protocol.hpp"

namespace xlate5::proto {

// Marlin's refusal texts (its STR_ERR_* strings), followed by ", Last Line: <n>".
inline constexpr std::string_view kErrChecksumMismatch = "checksum mismatch";
inline constexpr std::string_view kErrLineNumber = "Line Number is not Last Line Number+1";
inline constexpr std::string_view kErrNoChecksum = "No Checksum with line number";
inline constexpr std::string_view kErrNoLineNumber = "No Line Number with checksum";  // older Marlin; xlate5's sender side

// Line numbers a sender or firmware may use: Marlin's `long` on a 32-bit board. Outside it
// (or an N without a number) a line is refused, and last_N +- 1 never overflows (docs/limits.md).
inline constexpr std::int64_t kMaxLineNumber = 2147483647;

class LineChecker {
public:
    enum class Verdict {
        Take,       // queue `command`
        Duplicate,  // number is last_N or last_N - 1: a copy of a line already taken (Marlin drops it silently)
        Refuse,     // reply "Error:<why>, Last Line: <n>", "Resend: <n+1>", "ok"
    };
    struct Result {
        Verdict verdict = Verdict::Take;
        std::string_view why;                 // Refuse: one of the kErr* texts
        std::optional<std::int64_t> number;   // the line's N, when it has one
        std::string_view command;             // without N and checksum (comments kept)
    };
    // `strict_unnumbered`: refuse a checksum without a line number (older Marlin, and xlate5's
    // sender side); Marlin 2.1 takes such a line as an unnumbered command.
    explicit LineChecker(bool strict_unnumbered = false) : strict_unnumbered_(strict_unnumbered) {}

    Result check(std::string_view line);
    std::int64_t last_line() const { return last_n_; }
    // False (and nothing set) for a number outside +-kMaxLineNumber.
    bool set_last_line(std::int64_t n) {
        if (n < -kMaxLineNumber || n > kMaxLineNumber) return false;
        last_n_ = n;
        return true;
    }
    // The three reply lines for a refusal, in Marlin's words (the caller adds "\n" as it writes).
    std::string error_line(std::string_view why) const;
    std::string resend_line() const;

private:
    std::int64_t last_n_ = 0;
    bool strict_unnumbered_;
};

}  // namespace xlate5::proto
