// SPDX-License-Identifier: GPL-3.0-or-later
// The firmware side of the service, on a real link (stage: service, firmware end; may call
// firmware_protocol, link). The protocol itself (numbering, resync, greeting, faults) is the
// I/O-free FirmwareProtocol; this adapter feeds it the link's lines and one Asio timer, writes
// what it says to write and hands its replies to the service.
#pragma once
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "daemon/firmware_protocol.hpp"
#include "daemon/lifetime.hpp"
#include "daemon/link.hpp"

namespace xlate5 {

class FirmwareLink {
public:
    class Listener {
    public:
        virtual ~Listener() = default;
        virtual void firmware_ready(const std::vector<std::string>& m115) = 0;
        virtual void firmware_acked(std::uint64_t tag, std::string_view ok_payload) = 0;  // only tagged lines
        virtual void firmware_message(std::string_view line) = 0;                        // to relay to the sender
        virtual void firmware_fault(const std::string& why, std::size_t lines_not_executed) = 0;
        virtual void firmware_progress() = 0;  // room in the queue again
    };
    using State = FirmwareProtocol::State;

    FirmwareLink(std::shared_ptr<Link> link, FirmwareOptions options, Listener& listener);
    ~FirmwareLink();

    void start();    // wait for "start" (or boot_wait), then greet
    void restart();  // after a fault: forget everything queued, greet again
    // Queues one command (no line number, checksum or comment; it must fit: see fits()).
    // `tag` != 0 is reported back through firmware_acked with the ok's payload.
    void enqueue(std::string command, std::uint64_t tag = 0, std::uint64_t origin = 0);
    bool fits(std::string_view command) const { return proto_.fits(command); }
    std::size_t max_command() const { return proto_.max_command(); }
    std::size_t sender_lines_queued() const { return proto_.sender_lines_queued(); }
    std::size_t drop_unsent() { return proto_.drop_unsent(); }
    // Sends at once, unnumbered, ahead of the queue (the firmware's emergency parser). M112 also
    // stops: one fault, with the count of lines not executed.
    void send_now(std::string_view command);
    std::size_t queued() const { return proto_.queued(); }
    bool idle() const { return proto_.idle(); }
    State state() const { return proto_.state(); }
    int window() const { return proto_.window(); }
    const FirmwareStats& stats() const { return proto_.stats(); }
    const std::vector<std::string>& m115() const { return proto_.m115(); }
    Link& link() { return *link_; }

private:
    void after_event();  // carry out the protocol's actions, re-arm the timer

    std::shared_ptr<Link> link_;
    Listener& listener_;
    FirmwareProtocol proto_;
    asio::steady_timer timer_;
    std::optional<FirmwareProtocol::Time> armed_;
    Lifetime lifetime_;
};

}  // namespace xlate5
