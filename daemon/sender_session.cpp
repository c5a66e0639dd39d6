// SPDX-License-Identifier: GPL-3.0-or-later
#include "daemon/sender_session.hpp"

#include <spdlog/spdlog.h>

namespace xlate5 {

SenderSession::SenderSession(std::shared_ptr<Link> link, Host& host, std::string name)
    : link_(std::move(link)), host_(host), name_(std::move(name)) {}

SenderSession::~SenderSession() { link_->close(); }

void SenderSession::start() {
    // The service owns the session; the link's handlers must not keep it alive (guarded, not owning).
    link_->start(lifetime_.guard([this](std::string_view line) {
                     last_heard_ = std::chrono::steady_clock::now();
                     proto_.on_line(line, link_->line_cut(), link_->max_line);
                     after_event();
                 }),
                 lifetime_.guard([this](const std::string&) {
                     proto_.link_closed();
                     after_event();
                 }));
    link_->on_hangup(lifetime_.guard([this] {
        proto_.hung_up();
        after_event();
    }));
}

void SenderSession::close() { link_->close(); }

void SenderSession::write(const std::string& line) {
    if (!link_->open()) return;
    if (link_->unsent_bytes() > kMaxUnreadBytes) {
        // It writes and does not read: its replies would pile up here without bound.
        spdlog::warn("{}: more than {} bytes of replies unread: closing the connection", name_, kMaxUnreadBytes);
        link_->close();
        host_.sender_gone(*this);
        return;
    }
    link_->send(line + '\n');
}

void SenderSession::after_event() {
    // Host calls answer the sender (and so re-enter after_event): take the actions first.
    for (auto& a : proto_.take_actions()) {
        using K = SenderProtocol::Action::Kind;
        switch (a.kind) {
            case K::Write: write(a.text); break;
            case K::Command: host_.sender_command(*this, a.text, a.code, a.line_no, a.numbered); break;
            case K::Emergency: host_.sender_emergency(*this, a.text); break;
            case K::Identify: write(host_.sender_m115()); break;
            case K::Reset: host_.sender_reset(*this); break;
            case K::Refused: host_.sender_refused(*this, a.text, a.line_no, a.numbered, std::move(a.cause)); break;
            case K::Gone: host_.sender_gone(*this); break;
            case K::Left: host_.sender_left(*this); break;
        }
    }
}

}  // namespace xlate5
