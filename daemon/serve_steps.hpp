// SPDX-License-Identifier: GPL-3.0-or-later
// What the service does with a sender's line, as policy without I/O (stage: service middle; may
// call the translator's public API and line_protocol). Service drives it line by line and
// carries its verdicts out on the links; `serve --check` (plan_as_serve) drives the same class
// over a whole file, so what --check predicts is what serve does. Unit-tested without links or
// pseudo-terminals (tests/test_sender.cpp).
//
// The policy (docs/service.md, "What the sender sees"):
//  - refused before it is acknowledged: a move while the machine's position is unknown, a
//    command passed on as written that no firmware line can hold, a line the translator refuses;
//  - acknowledged by xlate5 once its firmware lines are queued, or by the firmware's own ok for
//    a wait or a report (answered_by_firmware), whose look-back output is released first;
//  - held: the look-back window's output until it is decided, a wait or report comes, the
//    sender pauses or leaves, or the service drains;
//  - taken from the senders only while the firmware is ready, its queue has room, the position
//    is not being asked and the service is not draining (gate()).
#pragma once
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "daemon/line_protocol.hpp"
#include "translators/kinematics/kinematics.hpp"
#include "translators/pipeline/translator.hpp"

namespace xlate5 {

// The firmware's line buffer as commands see it: N and the checksum take the rest.
struct LineRoom {
    std::size_t max_command = 0;
    bool fits(std::string_view command) const { return command.size() <= max_command; }
};

// Commands whose answer comes with (or before) the firmware's ok: the sender gets that ok, so
// reports arrive where it expects them and waits (M400, M109) stay truthful.
bool answered_by_firmware(const proto::Code& c);

// A command that does not fit a firmware line: F moves to a line of its own, a message is
// shortened; anything else cannot be sent (false).
bool split_for_firmware(const LineRoom& room, const std::string& command, std::vector<std::string>& parts);

// G28 that homes every axis (no axis of the machine named): the position is known again.
bool homes_all(const Machine& machine, std::string_view command);

class ServeSteps {
public:
    // Firmware lines, and the serials (count of lines translated) of the sender lines they
    // stand for: first .. first + span - 1.
    struct Batch {
        std::vector<std::string> translated;  // as the translator gave them
        std::vector<std::string> lines;       // as the firmware gets them
        std::size_t split = 0;                // commands split over more than one line
        bool changed = false;                 // a command split or shortened
        std::uint64_t first = 0, span = 0;
    };
    struct Step {
        std::string refused;            // non-empty: refused with this cause; nothing of it is queued
        bool too_long = false;          // refused because no firmware line holds it, not by the translator
        bool firmware_answers = false;  // its ok is the firmware's (tag its last line)
        Batch released;                 // the look-back's held output, released before it (a wait or report)
        std::string release_bad;        // non-empty: that output holds this command, which fits no firmware line
        Batch own;
    };
    enum class Position { Unknown, Asking, Known };
    // What the service does with the next line a sender wrote.
    enum class Gate { Take, Wait, Keep };  // Wait: the sender is kept waiting (busy); Keep: left unread (draining)
    struct QueueState {
        bool draining = false, stopped = false, firmware = false, firmware_ready = false;
        std::size_t queued = 0, queue_lines = 0;
    };

    ServeSteps(const Machine& machine, TranslatorOptions options, Position start = Position::Unknown);
    void reset(const Kinematics& kin);  // a fresh translator (the machine's start modes; the position kept)
    void set_room(LineRoom room) { room_ = room; }

    Step line(std::string_view command, const proto::Code& code, std::uint64_t line_no);
    // The end of the look-back window: what the translator holds is final. False, with the
    // command in `bad`, when it holds a command no firmware line can take.
    bool release(Batch& out, std::string& bad);
    Gate gate(const QueueState& q) const;

    // The machine's position: asked of the firmware whenever it is greeted.
    bool ask_position();                          // false while the look-back holds output: not now
    void position_unanswered();                   // the firmware's ok came without a report
    void position_read(const std::vector<double>* q, std::optional<double> e, const std::string& why);  // q null: unreadable
    void position_lost(const std::string& why);   // the firmware stopped
    Position position() const { return position_; }
    const std::string& position_why() const { return position_why_; }

    bool holding() const { return holding_; }
    std::uint64_t lines_in() const { return lines_in_; }
    Translator& translator() { return *translator_; }
    const Translator& translator() const { return *translator_; }

private:
    std::optional<std::string> unplaceable(const proto::Code& code) const;
    std::optional<std::string> unsendable(const proto::Code& code, std::string_view command) const;
    bool split(Batch& b, std::string& bad) const;
    void translate(std::string_view command, const proto::Code& code, std::uint64_t line_no, Step& s);

    const Machine* machine_;
    TranslatorOptions options_;
    std::unique_ptr<Translator> translator_;
    LineRoom room_;
    Position position_;
    std::string position_why_ = "the firmware has not reported it yet";
    bool holding_ = false;             // the translator may hold output (look-back)
    std::uint64_t lines_in_ = 0;       // lines translated (their serials)
    std::uint64_t window_first_ = 0;   // the serial of the look-back window's first line
    std::string out_;                  // translator output scratch
};

}  // namespace xlate5
