// SPDX-License-Identifier: GPL-3.0-or-later
#include "daemon/sender_session.hpp"

#include <cstdlib>
#include <spdlog/spdlog.h>

#include "daemon/line_protocol.hpp"

namespace xlate5 {

SenderSession::SenderSession(std::shared_ptr<Link> link, Host& host, std::string name)
    : link_(std::move(link)), host_(host), name_(std::move(name)) {}

SenderSession::~SenderSession() { link_->close(); }

void SenderSession::start() {
    // The service owns the session; the link's handlers must not keep it alive (guarded, not owning).
    link_->start(lifetime_.guard([this](std::string_view line) { on_line(line); }),
                 lifetime_.guard([this](const std::string&) { host_.sender_gone(*this); }));
    link_->on_hangup(lifetime_.guard([this] { host_.sender_left(*this); }));
}

void SenderSession::close() { link_->close(); }

void SenderSession::send_line(std::string_view line) {
    if (!link_->open()) return;
    if (link_->unsent_bytes() > kMaxUnreadBytes) {
        // It writes and does not read: its replies would pile up here without bound.
        spdlog::warn("{}: more than {} bytes of replies unread: closing the connection", name_, kMaxUnreadBytes);
        link_->close();
        host_.sender_gone(*this);
        return;
    }
    std::string s(line);
    s += '\n';
    link_->send(s);
}

void SenderSession::ok(std::string_view payload) {
    std::string s = "ok";
    s += payload;
    send_line(s);
}

void SenderSession::refuse(std::string_view why) {
    // Marlin's words, so a sender's resend logic works unchanged.
    send_line(checker_.error_line(why));
    send_line(checker_.resend_line());
    ok();
}

void SenderSession::on_line(std::string_view raw) {
    ++received_;
    last_heard_ = std::chrono::steady_clock::now();
    if (link_->line_cut()) {
        // Its middle is gone: neither its checksum nor its command can be trusted. Refused
        // clearly, never run cut (a numbered one ends the print; resending it would not help).
        const auto r = proto::parse_received(raw);
        const bool numbered = r.number && *r.number == checker_.last_line() + 1;
        if (numbered) checker_.set_last_line(*r.number);
        const std::string head(r.command.substr(0, 40));
        host_.sender_refused(*this, head + "...", numbered ? std::uint64_t(*r.number) : received_, numbered,
                             "longer than " + std::to_string(link_->max_line) + " bytes (the line-length bound)");
        return;
    }
    const auto v = checker_.check(raw);
    if (v.verdict == proto::LineChecker::Verdict::Refuse) return refuse(v.why);
    if (v.verdict == proto::LineChecker::Verdict::Duplicate) {
        // Marlin drops a repeat of its last line without a word; a sender that repeated it
        // because an ok was lost would then wait for ever. It is not run again, but answered.
        ok();
        return;
    }
    const std::string bare = proto::strip_comment(v.command);
    const auto code = proto::command_code(bare);
    const auto& r = v;
    if (bare.empty()) {
        if (r.number) ok();  // a numbered line that holds only a comment still counts
        return;
    }
    if (code.is('M', 110)) {
        // "M110 N<n>" (or the line's own number) sets the next expected line.
        if (const auto n = proto::m110_line(bare))
            if (!checker_.set_last_line(*n)) return refuse(proto::kErrLineNumber);  // beyond +-kMaxLineNumber
        host_.sender_reset(*this);
        ok();
        return;
    }
    if (code.is('M', 112) || code.is('M', 108) || code.is('M', 410)) {
        host_.sender_emergency(*this, bare);
        ok();
        return;
    }
    if (code.is('M', 115)) {
        send_line(host_.sender_m115());
        ok();
        return;
    }
    host_.sender_command(*this, v.command, code, r.number ? std::uint64_t(*r.number) : received_, r.number.has_value());
}

}  // namespace xlate5
