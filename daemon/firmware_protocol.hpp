// SPDX-License-Identifier: GPL-3.0-or-later
// The firmware side's protocol as a state machine with no I/O (stage: service, firmware end;
// may call line_protocol only). Events in: lines received, the clock passing a deadline,
// commands to send; actions out: text to write, replies for the sender side, faults. The Asio
// adapter (firmware_link) writes the text and arms one timer at deadline(); tests drive this
// class with scripted replies and a scripted clock.
//
// What it must survive is Marlin's receive rules (docs/service.md, "Marlin's receive rules"): a refused line
// empties the firmware's receive buffer, so the number of replies after an error does not
// follow from the lines sent, and a repeat of the last line is dropped without a word. Hence:
//  - after any Resend, line error or silence, nothing more is sent until the firmware has been
//    quiet for `settle` seconds (the reply timeout does not cut that wait short); then it is asked where it is with a harmless numbered M105 (the
//    probe), whose "ok T:" is the only reply that names itself; lines continue from the number
//    the firmware named (or after the probe, which it took);
//  - an ok with nothing in flight, or with an M105 first in flight (the oks before it all came),
//    means the firmware answers some lines more than once: from then
//    on (until the next greeting) lines go in groups, each with an M105 behind it, and only its
//    "ok T:" credits them, so what is in the firmware's buffer stays bounded;
//  - without ADVANCED_OK, plain oks are credited in order only while nothing went wrong; an
//    "ok T:" credits everything up to the M105 it answers; a line a sender waits on (M400, M114,
//    M105) goes alone, so its ok is its own; with ADVANCED_OK, "ok N<n>" credits up to n;
//  - silence is answered with a probe under a fresh number (never a repeat Marlin may drop),
//    and only `max_timeouts` probes in a row without any reply make the firmware "gone";
//  - Marlin only: a short silence (`nudge`) with lines in flight and nothing sent since is
//    answered first with one empty line: it ends a line whose newline was lost, and Marlin skips
//    an empty line without a reply, so it costs one byte and no reply timeout;
//  - the greeting (and M999) waits for quiet, sends M110 N0 and an unnumbered M115, takes the
//    firmware's word only from the FIRMWARE_NAME report on, waits for quiet again, and checks the
//    flavour. Marlin sets its line number again when M110 *runs* (PROTOCOL rule 6), so nothing
//    numbered follows an M110 until the firmware has answered a command queued behind it;
//  - a Resend that names the line after xlate5's latest M110, for a line already acknowledged,
//    means the firmware re-ran that M110: it is re-numbered (unnumbered M110, then an M105 whose
//    "ok T:" shows the M110 ran) rather than probed, which it would refuse again and again.
#pragma once
#include <chrono>
#include <cstdint>
#include <deque>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "daemon/line_protocol.hpp"

namespace xlate5 {

// Marlin's defaults (Configuration_adv.h) that a host has to respect.
namespace marlin {
inline constexpr std::size_t kMaxCmdSize = 96;        // MAX_CMD_SIZE: line buffer, terminator included
inline constexpr std::size_t kRxBufferSize = 128;     // RX_BUFFER_SIZE: serial receive buffer (bytes)
inline constexpr int kBufSize = 4;                    // BUFSIZE: commands queued
inline constexpr int kPlannerSize = 16;               // BLOCK_BUFFER_SIZE
inline constexpr double kKeepaliveSeconds = 2.0;      // DEFAULT_KEEPALIVE_INTERVAL
}  // namespace marlin

// Klipper's host side (klippy/gcode.py, GCodeIO and GCodeDispatch) as its pseudo-terminal shows it.
namespace klipper {
inline constexpr std::size_t kReadBytes = 4096;       // GCodeIO reads the pty 4096 bytes at a time
inline constexpr int kPendingStop = 20;               // lines pending while busy before it stops reading the pty
inline constexpr int kWindow = 16;                    // xlate5's lines in flight: below kPendingStop, so M112 is seen at once
inline constexpr int kNotReadyGreetings = 60;         // greetings (boot_wait apart) while STATUS says "not ready"
}  // namespace klipper

struct FirmwareOptions {
    bool reprap = false;            // RepRapFirmware: a bad line is dropped without a word; never more than one in flight
    bool klipper = false;           // Klipper's pty: plain lines, one ok each in order, "!!" errors (docs/firmware.md)
    int window = 0;                 // lines in flight; 0: 2, or learned from ADVANCED_OK's B
    std::size_t rx_bytes = marlin::kRxBufferSize - 1;  // bytes in flight at most (the firmware's serial receive buffer)
    std::size_t max_line = marlin::kMaxCmdSize;        // the firmware's line buffer, terminator included
    bool two_parts = true;          // Marlin: a line that does not fit rx_bytes whole goes in two parts (off: it waits whole; the bench compares)
    double reply_timeout = 5.0;     // seconds without a protocol reply while lines are in flight: probe
    double long_timeout = 900;      // RepRapFirmware only (it sends no keepalives): the same after homing, heating, dwelling
    double boot_wait = 2.0;         // seconds to wait for "start" after opening the port
    double settle = 0.25;           // seconds of quiet that end a resync or the greeting's wait
    double nudge = 0.05;            // Marlin: seconds of silence with lines in flight before one "\n" (0: never)
    int max_timeouts = 5;           // probes in a row without any reply before the firmware is declared gone
    int max_greetings = 4;          // greeting attempts before the firmware is declared unresponsive
    int max_resyncs = 20;           // resyncs in a row without a line acknowledged before "lost its place"
    std::size_t history = 512;      // acknowledged lines kept: a stray ok may have credited a line the firmware never took
};

struct FirmwareStats {
    std::uint64_t sent = 0, acked = 0, resent = 0, resend_requests = 0, timeouts = 0, busy = 0;
    std::uint64_t probes = 0, resyncs = 0, stray_oks = 0, greetings = 0, nudges = 0, renumbers = 0;
};

class FirmwareProtocol {
public:
    using Clock = std::chrono::steady_clock;
    using Time = Clock::time_point;

    enum class State { Booting, Greeting, Ready, Faulted };
    struct Action {
        enum class Kind { Write, Ready, Acked, Message, Fault, Progress } kind;
        std::string text;         // Write: bytes; Message: a line for the sender; Fault: why; Acked: ok payload
        std::uint64_t tag = 0;    // Acked
        std::size_t lost = 0;     // Fault: lines not known to be executed (unsent or unconfirmed)
    };

    explicit FirmwareProtocol(FirmwareOptions options);

    // Events.
    void open(Time now);                                   // the port is open: wait for "start" (or boot_wait)
    void restart(Time now);                                // M999: forget the queue, greet again
    void on_line(std::string_view line, Time now);
    void on_time(Time now);                                // the clock reached deadline()
    // tag != 0: reported with Acked. origin: the sender's line it comes from (0: none), so a
    // fault counts the sender's lines not executed, not the firmware lines they became.
    void enqueue(std::string command, std::uint64_t tag, Time now, std::uint64_t origin = 0);
    void send_unnumbered(std::string_view command, Time now);        // M108, M410: ahead of the queue
    void emergency_stop(std::string_view command, Time now);         // M112: ahead of everything; one Fault
    void port_closed(const std::string& why);
    std::size_t drop_unsent();

    // Actions since the last call, in order.
    std::vector<Action> take_actions() { return std::exchange(actions_, {}); }
    std::optional<Time> deadline() const;

    bool fits(std::string_view command) const;  // within the firmware's line buffer with N and checksum
    std::size_t max_command() const;            // the longest command that fits
    std::size_t queued() const { return unsent_.size() + in_flight_.size(); }
    bool idle() const { return queued() == 0; }
    std::size_t sender_lines_queued() const;  // of the sender's lines (Item::origin), queued or unconfirmed
    State state() const { return state_; }
    int window() const;
    bool advanced_ok() const { return advanced_ok_; }
    const FirmwareStats& stats() const { return stats_; }
    const std::vector<std::string>& m115() const { return m115_; }

private:
    struct Item { std::string command; std::uint64_t tag = 0; std::uint64_t origin = 0; };
    struct Entry {
        std::int64_t n = -1;      // -1: unnumbered
        std::string command;
        std::uint64_t tag = 0;
        std::size_t bytes = 0;
        bool anchor = false;      // an M105: its "ok T:" names it
        bool probe = false;       // sent by xlate5 to learn where the firmware is
        std::uint64_t origin = 0; // the sender's line (Item::origin)
    };
    enum class Sync { None, Quiet, Probing };
    enum class Greet { Quiet, AwaitReport, Settle };

    void emit(Action::Kind k, std::string text = {}, std::uint64_t tag = 0, std::size_t lost = 0) {
        actions_.push_back({k, std::move(text), tag, lost});
    }
    void write_line(const std::string& line);
    void greet(Time now);
    void send_greeting(Time now);
    void become_ready();
    void transmit(Time now);
    void transmit_klipper(Time now);
    void on_klipper_line(const proto::Reply& r, std::string_view line, Time now);
    void on_klipper_greeting(const proto::Reply& r, std::string_view line, Time now);
    std::size_t budget() const { return opt_.klipper ? klipper::kReadBytes - 1 : opt_.rx_bytes; }
    void send_entry(Entry e, Time now, std::size_t room = SIZE_MAX);
    bool write_tail();
    void finish_tail();
    void abandon_tail();
    void credit_front(std::string_view payload);
    void credit_through(std::size_t index, std::string_view payload);
    void on_ok(const proto::Reply& r, Time now);
    void on_refusal(std::optional<std::int64_t> next, bool confirmed, Time now);
    void end_quiet(Time now);
    void send_probe(std::int64_t n, Time now);
    void send_renumber(Time now);
    bool own_fragment(std::string_view line) const;
    void rewind(std::int64_t k);
    void on_reply_timeout(Time now);
    void arm_nudge(Time now);
    void on_nudge();
    void fault(const std::string& why);
    void progressed() { resyncs_in_row_ = 0; timeouts_in_row_ = 0; }

    FirmwareOptions opt_;
    State state_ = State::Booting;
    std::vector<Action> actions_;

    std::deque<Item> unsent_;
    std::deque<Entry> in_flight_;
    std::deque<Entry> history_;       // acknowledged numbered lines, oldest first
    std::size_t bytes_in_flight_ = 0;  // of every line in flight, the unwritten tail included
    std::string tail_;                 // the unwritten end of the newest line in flight (sent in two parts)
    bool m999_after_quiet_ = false;    // restart(): M999 goes once the refusal of a half-sent line is over
    std::size_t tagged_in_flight_ = 0;
    std::int64_t next_n_ = 0;         // number for the next line
    std::int64_t max_sent_n_ = -1;    // highest number written since the greeting
    std::int64_t credited_n_ = -1;    // highest number acknowledged by the firmware

    Sync sync_ = Sync::None;
    std::optional<std::int64_t> resend_from_;  // the line the firmware named in this resync
    std::optional<std::int64_t> error_next_;   // the line after "Last Line: n" of the latest Error
    std::int64_t last_m110_ = 0;               // the number xlate5's latest M110 set
    bool renumber_ = false;                    // this resync ends with a re-numbering, not a probe
    bool extra_oks_ = false;                   // the firmware answered a line more than once: only M105 anchors credit
    Greet greet_ = Greet::Quiet;
    int greetings_ = 0;

    std::optional<Time> boot_deadline_, quiet_deadline_, reply_deadline_;
    std::optional<Time> nudge_deadline_;  // armed by a line sent, pushed on by each reply, once per line sent
    int timeouts_in_row_ = 0, resyncs_in_row_ = 0, long_waits_ = 0;
    bool advanced_ok_ = false;
    int learned_window_ = 0;
    std::vector<std::string> m115_;
    FirmwareStats stats_;
    // Klipper: the STATUS of the greeting ("// Klipper state: Ready", or an "!!" when not ready),
    // the greetings made while it was not ready, and GET_POSITION's "gcode:" and "gcode base:"
    // lines (its answer to the M114 xlate5 was asked for).
    bool klipper_ready_ = false;
    std::string klipper_not_ready_;
    int klipper_waits_ = 0;
    double klipper_silence_ = 0;
    std::string klipper_gcode_, klipper_base_;
};

}  // namespace xlate5
