// SPDX-License-Identifier: GPL-3.0-or-later
// The sender side's protocol as a state machine with no I/O, the mirror of FirmwareProtocol
// (stage: service, sender end; may call line_checker, line_protocol only). xlate5 plays the
// printer here: events in are the lines a sender wrote and the service's verdicts on its
// commands; actions out are the lines to write back (ok, Error:, Resend:, echo:, action
// commands) and what to hand the service (a command for the queue, an emergency command, …).
// The Asio adapter (sender_session) feeds it the link's lines and carries its actions out;
// tests drive it with scripted lines.
//
// Received lines follow Marlin's receive rules (docs/service.md, "Marlin's receive rules"),
// never more lenient: a skipped number, a bad checksum, a number without a checksum or a
// checksum without a number get Marlin's Error:/Resend:/ok; M110 N<n> sets the next number.
// Two deliberate differences: a repeat of the last line (or the one before) is answered ok
// where Marlin drops it silently (it is still not run: a sender that repeated it because an ok
// was lost would otherwise wait for ever), and a line longer than the link's buffer is refused
// whole rather than run cut.
#pragma once
#include <cstdint>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "daemon/line_checker.hpp"
#include "daemon/line_protocol.hpp"

namespace xlate5 {

class SenderProtocol {
public:
    struct Action {
        enum class Kind {
            Write,      // text: one reply line, without its '\n'
            Command,    // text: a command for the queue (comments kept), with code, line_no, numbered
            Emergency,  // text: M112, M108 or M410, to the firmware ahead of the queue
            Identify,   // M115: write the service's M115 report (the ok follows as its own Write)
            Reset,      // M110: the sender numbers its lines anew (a new print)
            Refused,    // text: a line that cannot be taken whole, refused in its turn with `cause`
            Gone,       // the link closed (TCP): the session ends
            Left,       // the sender closed the pseudo-terminal: it may come back
        } kind;
        std::string text;
        proto::Code code = {};
        std::uint64_t line_no = 0;  // the N word, or the count of lines received for an unnumbered one
        bool numbered = false;      // it came with N and a checksum (a print's line, not a terminal's)
        std::string cause = {};     // Refused
    };

    // Events from the link.
    // `cut`: the link kept only the line's first `max_line` bytes (its middle is lost).
    void on_line(std::string_view line, bool cut = false, std::size_t max_line = 0);
    void link_closed() { emit(Action::Kind::Gone); }
    void hung_up() { emit(Action::Kind::Left); }

    // Events from the service: its answers to a command it was handed.
    void ok(std::string_view payload = {});   // taken (or answered by the firmware with `payload`)
    void say(std::string_view line) { emit(Action::Kind::Write, std::string(line)); }  // a report, a relayed message
    void busy() { say("echo:busy: processing"); }  // the queue is full: the ok is late (Marlin's keepalive)
    // Refused in its turn (`quoted`: "line <n> '<command>': <cause>"). A typed line is refused
    // alone; a print's line ends the print (docs/service.md, "A line xlate5 refuses").
    void refused(std::string_view quoted, bool numbered);
    // Not run: the print was cancelled (`healthy`: the printer is fine, so not an Error:, which
    // OctoPrint answers with M112) or the firmware stopped.
    void not_run(std::string_view command, std::string_view reason, bool healthy);
    // Another sender prints: the command was not run.
    void turned_away(std::string_view why);

    // Actions since the last call, in order.
    std::vector<Action> take_actions() { return std::exchange(actions_, {}); }
    std::int64_t last_line() const { return checker_.last_line(); }

private:
    void emit(Action::Kind k, std::string text = {}) { actions_.push_back({k, std::move(text)}); }
    void refuse(std::string_view why);
    void on_cut_line(std::string_view line, std::size_t max_line);

    proto::LineChecker checker_{/*strict_unnumbered=*/true};
    std::uint64_t received_ = 0;
    std::vector<Action> actions_;
};

}  // namespace xlate5
