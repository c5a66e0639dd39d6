// SPDX-License-Identifier: GPL-3.0-or-later
#include "daemon/sender_protocol.hpp"

namespace xlate5 {

void SenderProtocol::ok(std::string_view payload) {
    std::string s = "ok";
    s += payload;
    emit(Action::Kind::Write, std::move(s));
}

void SenderProtocol::refuse(std::string_view why) {
    // Marlin's words, so a sender's resend logic works unchanged.
    say(checker_.error_line(why));
    say(checker_.resend_line());
    ok();
}

void SenderProtocol::on_cut_line(std::string_view line, std::size_t max_line) {
    // Its middle is gone: neither its checksum nor its command can be trusted. Refused clearly,
    // never run cut (a numbered one ends the print; resending it would not help).
    const auto r = proto::parse_received(line);
    const bool numbered = r.number && *r.number == checker_.last_line() + 1;
    if (numbered) checker_.set_last_line(*r.number);
    Action a{Action::Kind::Refused, std::string(r.command.substr(0, 40)) + "..."};
    a.line_no = numbered ? std::uint64_t(*r.number) : received_;
    a.numbered = numbered;
    a.cause = "longer than " + std::to_string(max_line) + " bytes (the line-length bound)";
    actions_.push_back(std::move(a));
}

void SenderProtocol::on_line(std::string_view line, bool cut, std::size_t max_line) {
    ++received_;
    if (cut) return on_cut_line(line, max_line);
    const auto v = checker_.check(line);
    if (v.verdict == proto::LineChecker::Verdict::Refuse) return refuse(v.why);
    if (v.verdict == proto::LineChecker::Verdict::Duplicate) return ok();  // not run again, but answered
    const std::string bare = proto::strip_comment(v.command);
    if (bare.empty()) {
        if (v.number) ok();  // a numbered line that holds only a comment still counts
        return;
    }
    const auto code = proto::command_code(bare);
    if (code.is('M', 110)) {
        // "M110 N<n>" (or the line's own number) sets the next expected line.
        if (const auto n = proto::m110_line(bare))
            if (!checker_.set_last_line(*n)) return refuse(proto::kErrLineNumber);  // beyond +-kMaxLineNumber
        emit(Action::Kind::Reset);
        return ok();
    }
    if (code.is('M', 112) || code.is('M', 108) || code.is('M', 410)) {
        emit(Action::Kind::Emergency, bare);
        return ok();
    }
    if (code.is('M', 115)) {
        emit(Action::Kind::Identify);
        return ok();
    }
    Action a{Action::Kind::Command, std::string(v.command), code};
    a.line_no = v.number ? std::uint64_t(*v.number) : received_;
    a.numbered = v.number.has_value();
    actions_.push_back(std::move(a));
}

void SenderProtocol::refused(std::string_view quoted, bool numbered) {
    // OctoPrint takes any Error: that is not about line numbers or checksums as fatal and sends
    // M112 to a healthy printer: a refused line is told with echo: and an action command.
    const std::string q(quoted);
    if (!numbered) {
        // Typed in a terminal: refused, and nothing else changes.
        say("echo:xlate5: refused " + q);
        say("//action:notification xlate5: refused " + q);
        return ok();
    }
    // Part of a print: the print ends there.
    say("//action:cancel");
    say("echo:xlate5: print cancelled at " + q);
    say("//action:notification xlate5: print cancelled at " + q);
    ok();
}

void SenderProtocol::not_run(std::string_view command, std::string_view reason, bool healthy) {
    if (healthy)
        say("echo:xlate5: not run: '" + std::string(command) + "' (" + std::string(reason) + "); start a new print or send M999");
    else
        say("Error:Printer stopped (xlate5): " + std::string(reason) + ". Fix the cause and send M999 to restart.");
    ok();
}

void SenderProtocol::turned_away(std::string_view why) {
    say("echo:" + std::string(why));
    say("//action:notification " + std::string(why));
    ok();
}

}  // namespace xlate5
