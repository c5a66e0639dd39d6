#include "daemon/sender_session.hpp"

#include <cstdlib>

#include "daemon/line_protocol.hpp"

namespace xlate5 {

SenderSession::SenderSession(std::shared_ptr<Link> link, Host& host, std::string name)
    : link_(std::move(link)), host_(host), name_(std::move(name)) {}

SenderSession::~SenderSession() { link_->close(); }

void SenderSession::start() {
    // Weak: the service owns the session; the link must not keep it alive in a cycle.
    std::weak_ptr<SenderSession> weak = shared_from_this();
    link_->start([weak](std::string_view line) {
        if (auto self = weak.lock()) self->on_line(line);
    }, [weak](const std::string&) {
        if (auto self = weak.lock()) self->host_.sender_gone(*self);
    });
}

void SenderSession::close() { link_->close(); }

void SenderSession::send_line(std::string_view line) {
    std::string s(line);
    s += '\n';
    link_->send(s);
}

void SenderSession::ok(std::string_view payload) {
    std::string s = "ok";
    s += payload;
    send_line(s);
}

void SenderSession::refuse(const char* why) {
    // Marlin's words, so a sender's resend logic works unchanged.
    send_line(std::string("Error:") + why + ", Last Line: " + std::to_string(last_n_));
    send_line("Resend: " + std::to_string(last_n_ + 1));
    ok();
}

void SenderSession::on_line(std::string_view raw) {
    const auto r = proto::parse_received(raw);
    ++received_;
    const std::string bare = proto::strip_comment(r.command);
    const auto code = proto::command_code(bare);
    if (r.number) {
        if (!r.has_checksum) return refuse("No Checksum with line number");
        if (!r.checksum_ok) return refuse("checksum mismatch");
        if (!code.is('M', 110) && *r.number != last_n_ + 1) return refuse("Line Number is not Last Line Number+1");
        last_n_ = *r.number;
    } else if (r.has_checksum) {
        return refuse("No Line Number with checksum");
    }
    if (bare.empty()) {
        if (r.number) ok();  // a numbered line that holds only a comment still counts
        return;
    }
    if (code.is('M', 110)) {
        // "M110 N<n>" (or the line's own number) sets the next expected line.
        if (const auto n = proto::m110_line(bare)) last_n_ = *n;
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
    host_.sender_command(*this, r.command, code, r.number ? std::uint64_t(*r.number) : received_);
}

}  // namespace xlate5
