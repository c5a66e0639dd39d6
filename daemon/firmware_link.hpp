// The firmware side of the service: numbers and checksums every line, keeps a window of
// unacknowledged lines sized to the firmware's buffer, answers Resend/rs from a history of sent
// lines (whether or not an ok follows), recovers silently dropped lines by timeout, and turns a
// reset, a kill or a vanished port into one clear fault: the print stops, nothing is replayed.
#pragma once
#include <cstdint>
#include <deque>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "daemon/line_protocol.hpp"
#include "daemon/link.hpp"

namespace xlate5 {

struct FirmwareOptions {
    bool reprap = false;            // RepRapFirmware: a bad line is dropped without a word; never more than one in flight
    int window = 0;                 // lines in flight; 0: 2, or learned from ADVANCED_OK's B
    std::size_t rx_bytes = 127;     // bytes in flight at most (the firmware's serial receive buffer)
    std::size_t max_line = 96;      // the firmware's line buffer, terminator included (Marlin MAX_CMD_SIZE)
    double reply_timeout = 5.0;     // seconds without a reply while lines are in flight: resend the oldest
    double long_timeout = 900;      // the same after homing, heating, dwelling (RRF is silent meanwhile)
    double boot_wait = 2.0;         // seconds to wait for "start" after opening the port
    int max_timeouts = 5;           // consecutive timeouts before the firmware is declared gone
    std::size_t history = 512;      // sent lines kept for Resend
};

struct FirmwareStats {
    std::uint64_t sent = 0, acked = 0, resent = 0, resend_requests = 0, timeouts = 0, busy = 0;
};

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
    enum class State { Booting, Hello, Ready, Faulted };

    FirmwareLink(std::shared_ptr<Link> link, FirmwareOptions options, Listener& listener);
    ~FirmwareLink();

    void start();    // wait for "start" (or boot_wait), then M110 N0 and M115
    void restart();  // after a fault: forget everything queued, say hello again
    // Queues one command (no line number, checksum or comment; it must fit: see fits()).
    // `tag` != 0 is reported back through firmware_acked with the ok's payload.
    void enqueue(std::string command, std::uint64_t tag = 0);
    bool fits(std::string_view command) const;  // within the firmware's line buffer with N and checksum
    // Forgets the lines not yet sent (an emergency stop): what is in flight stays accounted for.
    std::size_t drop_unsent() {
        const auto n = waiting_.size();
        waiting_.clear();
        return n;
    }
    // Sends at once, unnumbered, ahead of the queue (M112, M108, M410: the firmware's emergency parser).
    void send_now(std::string_view command);
    std::size_t queued() const { return waiting_.size() + unsent_numbered() + in_flight_.size(); }
    bool idle() const { return queued() == 0; }
    State state() const { return state_; }
    int window() const;
    const FirmwareStats& stats() const { return stats_; }
    const std::vector<std::string>& m115() const { return m115_; }
    Link& link() { return *link_; }

private:
    struct Waiting { std::string command; std::uint64_t tag; };
    struct Sent { std::string text; std::uint64_t tag; };              // text: "N.. cmd*cs\n"
    struct Flight { std::int64_t n; std::uint64_t epoch; std::size_t bytes; };  // n < 0: unnumbered

    void on_line(std::string_view line);
    void on_ok(const proto::Reply& reply);
    void on_resend(std::int64_t n);
    void hello();
    void transmit();
    void acknowledge(std::int64_t n, std::string_view payload);
    void fault(const std::string& why);
    void arm_timer();
    void on_timeout();
    std::size_t unsent_numbered() const { return std::size_t(last_n_ + 1 - next_tx_); }
    std::size_t bytes_in_flight() const;

    std::shared_ptr<Link> link_;
    FirmwareOptions opt_;
    Listener& listener_;
    State state_ = State::Booting;
    asio::steady_timer boot_timer_, reply_timer_;

    std::deque<Waiting> waiting_;       // not yet numbered
    std::deque<Sent> sent_;             // numbered lines first_n_ .. last_n_ (history and not yet sent)
    std::int64_t first_n_ = 0, last_n_ = -1, next_tx_ = 0;
    std::deque<Flight> in_flight_;      // transmitted, awaiting their ok
    std::uint64_t epoch_ = 0;           // bumped by each rewind: older flights will be refused
    // Whether this firmware follows Resend with an ok (Marlin mostly does, some versions do not):
    // learned from the first Resend. Until the line after a Resend has come (or a short grace
    // has passed), nothing is sent, so an ok there can only belong to the refused line.
    enum class ResendOk { Unknown, Yes, No } resend_ok_ = ResendOk::Unknown;
    bool after_resend_ = false;
    asio::steady_timer grace_timer_;
    bool probing_ = false;              // a line was resent after a timeout
    int timeouts_in_row_ = 0;
    int long_waits_ = 0;              // reply timeouts spent waiting on a long command
    int learned_window_ = 0;
    std::int64_t hello_m115_ = -1;      // line number of the hello's M115
    std::vector<std::string> m115_;
    FirmwareStats stats_;
    std::shared_ptr<bool> alive_ = std::make_shared<bool>(true);
};

}  // namespace xlate5
