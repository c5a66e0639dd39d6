// SPDX-License-Identifier: GPL-3.0-or-later
// The host line protocol that Marlin and RepRapFirmware speak (and senders expect of them):
// "N<n> <command>*<checksum>" lines, the XOR checksum, and the shape of the replies. Pure text
// functions, shared by both sides of the service and by the virtual printer. Stage: the
// service's wire format; calls nothing.
#pragma once
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace xlate5::proto {

// XOR of every byte, as Marlin and RRF compute it over "N<n> <command>".
std::uint8_t checksum(std::string_view text);

// "N<n> <command>*<cs>" for the firmware.
std::string numbered(std::int64_t n, std::string_view command);

// A received line, taken apart. `command` is what is left without N, checksum, comment and
// surrounding blanks.
struct Received {
    std::optional<std::int64_t> number;   // the N word, when the line starts with one
    bool bad_number = false;              // it starts with N, but no number follows (a damaged line)
    bool has_checksum = false;
    bool checksum_ok = true;              // true when there is no checksum to check
    std::string_view command;
};
Received parse_received(std::string_view line);

// The command without comments (';' to the end, '( … )') and surrounding blanks: what a
// firmware with a small line buffer needs to see.
std::string strip_comment(std::string_view command);

// The commands in a block of translator output: one a line, comments stripped, blanks skipped.
void append_commands(std::string_view text, std::vector<std::string>& out);

// The line number "M110 N<n>" sets, when the command names one.
std::optional<std::int64_t> m110_line(std::string_view command);

// The G or M code a command starts with, e.g. ('M', 1150) for "M115" (code x10, so G43.4 is 434);
// letter 0 when the command does not start with one, or with a code beyond +-100000.
struct Code {
    char letter = 0;
    int code10 = 0;
    bool is(char l, int code) const { return letter == l && code10 == code * 10; }
};
Code command_code(std::string_view command);

// Replies from the firmware, classified.
enum class ReplyKind {
    Ok,          // "ok", with ADVANCED_OK "ok N<n> P<p> B<b>", or "ok T:…" carrying a report
    Resend,      // "Resend: n", "rs n"
    Busy,        // "echo:busy: processing" / "busy: …" (host keepalive)
    Wait,        // "wait" (Marlin idle, nothing to do)
    Start,       // "start": the firmware (re)booted
    Halted,      // "Error:Printer halted…", "kill()", "Printer stopped"
    LineError,   // "Error:checksum mismatch…", "Error:Line Number…", "Error:No Checksum…": the next line is a Resend
    Error,       // any other "Error:…"
    Other,       // echo:, temperatures, positions, Cap: lines, anything else
};
struct Reply {
    ReplyKind kind = ReplyKind::Other;
    std::int64_t resend_line = -1;          // Resend
    std::optional<std::int64_t> ok_line;    // ADVANCED_OK N
    std::optional<int> planner_free;        // ADVANCED_OK P
    std::optional<int> buffer_free;         // ADVANCED_OK B
    std::string_view payload;               // Ok: what follows "ok" (e.g. " T:20.0 /0.0")
};
Reply classify(std::string_view line);

}  // namespace xlate5::proto
