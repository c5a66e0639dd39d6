// SPDX-License-Identifier: GPL-3.0-or-later
#include "daemon/firmware_link.hpp"

#include <spdlog/spdlog.h>

namespace xlate5 {
namespace {
FirmwareProtocol::Time now() { return FirmwareProtocol::Clock::now(); }
}  // namespace

FirmwareLink::FirmwareLink(std::shared_ptr<Link> link, FirmwareOptions options, Listener& listener)
    : link_(std::move(link)), listener_(listener), proto_(options), timer_(link_->stream_executor()) {}

FirmwareLink::~FirmwareLink() { link_->close(); }

void FirmwareLink::start() {
    link_->start(lifetime_.guard([this](std::string_view line) {
                     spdlog::trace("firmware> {}", line);
                     proto_.on_line(line, now());
                     after_event();
                 }),
                 lifetime_.guard([this](const std::string& why) {
                     if (why.empty()) return;
                     proto_.port_closed("the port " + link_->name() + " closed: " + why);
                     after_event();
                 }));
    proto_.open(now());
    after_event();
}

void FirmwareLink::restart() {
    if (!link_->open()) return;
    proto_.restart(now());
    after_event();
}

void FirmwareLink::enqueue(std::string command, std::uint64_t tag, std::uint64_t origin) {
    proto_.enqueue(std::move(command), tag, now(), origin);
    after_event();
}

void FirmwareLink::send_now(std::string_view command) {
    if (proto::command_code(command).is('M', 112)) proto_.emergency_stop(command, now());
    else proto_.send_unnumbered(command, now());
    after_event();
}

void FirmwareLink::after_event() {
    // Listener calls may enqueue more (and so re-enter after_event): take the actions first.
    for (auto& a : proto_.take_actions()) {
        using K = FirmwareProtocol::Action::Kind;
        switch (a.kind) {
            case K::Write:
                spdlog::trace("firmware< {}", std::string_view(a.text).substr(0, a.text.size() - 1));
                link_->send(a.text);
                break;
            case K::Ready: listener_.firmware_ready(proto_.m115()); break;
            case K::Acked: listener_.firmware_acked(a.tag, a.text); break;
            case K::Message: listener_.firmware_message(a.text); break;
            case K::Fault: listener_.firmware_fault(a.text, a.lost); break;
            case K::Progress: listener_.firmware_progress(); break;
        }
    }
    const auto d = proto_.deadline();
    if (!d) {
        armed_.reset();
        timer_.cancel();
        return;
    }
    if (armed_ && *armed_ == *d) return;  // already armed for it
    armed_ = d;
    timer_.expires_at(*d);
    timer_.async_wait(lifetime_.guard([this](boost::system::error_code ec) {
        if (ec) return;  // re-armed or cancelled
        armed_.reset();
        proto_.on_time(now());
        after_event();
    }));
}

}  // namespace xlate5
