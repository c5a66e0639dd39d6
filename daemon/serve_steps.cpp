// SPDX-License-Identifier: GPL-3.0-or-later
#include "daemon/serve_steps.hpp"

#include <cctype>

#include "translators/error.hpp"
#include "translators/pipeline/interpreter.hpp"

namespace xlate5 {

// M114 prints joints to two decimals: a report this close to the translator's joints is them.
static constexpr double kReportResolution = 0.005;

bool answered_by_firmware(const proto::Code& c) {
    if (c.letter != 'M') return false;
    switch (c.code10 / 10) {
        case 20: case 27: case 31: case 105: case 109: case 114: case 119: case 190: case 211: case 400: case 503:
            return c.code10 % 10 == 0;
        default:
            return false;
    }
}

bool split_for_firmware(const LineRoom& room, const std::string& cmd, std::vector<std::string>& parts) {
    parts.clear();
    if (room.fits(cmd)) {
        parts.push_back(cmd);
        return true;
    }
    const auto code = proto::command_code(cmd);
    if (code.letter == 'G' && (code.code10 == 0 || code.code10 == 10)) {
        const auto f = cmd.find(" F");
        if (f != std::string::npos) {
            auto end = cmd.find(' ', f + 1);
            const std::string fword = cmd.substr(f + 1, end == std::string::npos ? std::string::npos : end - f - 1);
            std::string rest = cmd.substr(0, f) + (end == std::string::npos ? "" : cmd.substr(end));
            const std::string feed = cmd.substr(0, cmd.find(' ')) + " " + fword;
            if (room.fits(feed) && room.fits(rest)) {
                parts.push_back(feed);  // F alone moves nothing and sets the feed for the next line
                parts.push_back(rest);
                return true;
            }
        }
        return false;
    }
    if (code.letter == 'M' && (code.code10 == 1170 || code.code10 == 1180)) {
        std::string s = cmd;
        while (!s.empty() && !room.fits(s)) s.pop_back();
        parts.push_back(s);
        return true;
    }
    return false;
}

bool homes_all(const Machine& machine, std::string_view command) {
    // The interpreter's own axis letters (is_axis_letter), so a machine's joint named by any
    // letter counts; the code itself is skipped.
    const std::string text = proto::strip_comment(command);
    const auto space = text.find(' ');
    if (space == std::string::npos) return true;
    for (std::size_t i = space; i < text.size(); ++i)
        if (is_axis_letter(machine, char(std::toupper(static_cast<unsigned char>(text[i]))))) return false;
    return true;
}

ServeSteps::ServeSteps(const Machine& machine, TranslatorOptions options, Position start)
    : machine_(&machine), options_(std::move(options)), position_(start) {}

void ServeSteps::reset(const Kinematics& kin) {
    // A fresh interpreter: modal state from the machine file, position unknown until homed or
    // placed; the same look-back window as offline translation (output held until decided).
    translator_.reset();
    translator_ = std::make_unique<Translator>(kin, options_);
    translator_->set_lookback(Translator::kDefaultLookback);
    holding_ = false;
}

std::optional<std::string> ServeSteps::unplaceable(const proto::Code& code) const {
    // While the position is unknown, only homing may move the machine.
    if (position_ != Position::Unknown || code.letter != 'G') return std::nullopt;
    const int g = code.code10;
    if (g != 0 && g != 10 && g != 20 && g != 30) return std::nullopt;
    return "the printer's position is not known (" + position_why_ + "): home it (G28) first";
}

std::optional<std::string> ServeSteps::unsendable(const proto::Code& code, std::string_view command) const {
    // A command passed on as written (not a move) that no firmware line could hold: refused
    // before the sender is answered, so that the lines acknowledged before it never wait behind
    // a line that cannot be sent (docs/service.md).
    if (code.letter == 'G' && code.code10 <= 30 && code.code10 % 10 == 0) return std::nullopt;  // G0-G3: written anew
    const std::string text = proto::strip_comment(command);
    std::vector<std::string> parts;
    if (split_for_firmware(room_, text, parts)) return std::nullopt;
    return "'" + text + "' is longer than the firmware's line buffer (" + std::to_string(room_.max_command) +
           " characters with its line number and checksum)";
}

bool ServeSteps::split(Batch& b, std::string& bad) const {
    std::vector<std::string> parts;
    for (const auto& cmd : b.translated) {
        if (!split_for_firmware(room_, cmd, parts)) {
            bad = cmd;
            return false;
        }
        if (parts.size() > 1) ++b.split;
        if (parts.size() > 1 || parts[0] != cmd) b.changed = true;
        for (auto& part : parts) b.lines.push_back(std::move(part));
    }
    return true;
}

bool ServeSteps::release(Batch& out, std::string& bad) {
    if (!holding_ || !translator_) return true;
    holding_ = false;
    out_.clear();
    translator_->finish(out_);
    proto::append_commands(out_, out.translated);
    // The output covers the window's lines, which the translator does not mark one by one.
    out.first = window_first_;
    out.span = lines_in_ - window_first_ + 1;
    return split(out, bad);
}

void ServeSteps::translate(std::string_view command, const proto::Code& code, std::uint64_t line_no, Step& s) {
    // A wait or a report (M400, M114, M109 …) is answered by the firmware once everything
    // before it ran: the look-back window ends there.
    if (s.firmware_answers && !release(s.released, s.release_bad)) s.released.lines.clear();
    const bool was_holding = holding_;
    if (was_holding) s.own.first = window_first_;
    out_.clear();
    try {
        translator_->feed(command, line_no, out_);
    } catch (const InputError& e) {
        s.refused = e.message();
        return;
    }
    // Held only while a look-back window is open: with none, there is nothing undecided to wait
    // for (no hold at the end of a print whose last window has closed).
    holding_ = translator_->holding();
    // A window opens here (or a new one after the old one's output came out).
    if (holding_ && (!was_holding || !out_.empty())) window_first_ = lines_in_;
    if (out_.empty()) s.own.first = lines_in_;
    proto::append_commands(out_, s.own.translated);
    if (code.is('G', 28) && position_ == Position::Unknown && homes_all(*machine_, command)) position_ = Position::Known;
}

ServeSteps::Step ServeSteps::line(std::string_view command, const proto::Code& code, std::uint64_t line_no) {
    Step s;
    if (const auto why = unplaceable(code)) {
        s.refused = *why;
        return s;
    }
    if (const auto why = unsendable(code, command)) {
        s.refused = *why;
        s.too_long = true;
        return s;
    }
    ++lines_in_;
    s.firmware_answers = answered_by_firmware(code);
    // The sender lines this line's output stands for: its own, and those of the look-back window
    // it may release.
    s.own.first = lines_in_;
    if (code.is('M', 105)) {
        // Temperatures: nothing to translate, and no reason to end the look-back window.
        s.own.translated.push_back(proto::strip_comment(command));
    } else {
        translate(command, code, line_no, s);
        if (!s.refused.empty()) return s;
    }
    s.own.span = lines_in_ - s.own.first + 1;
    std::string bad;
    if (!split(s.own, bad)) {
        s.refused = "'" + bad + "' is longer than the firmware's line buffer";
        s.too_long = true;
    }
    return s;
}

ServeSteps::Gate ServeSteps::gate(const QueueState& q) const {
    // While draining for a stop, lines not yet acknowledged stay with the sender, unsent.
    if (q.draining) return Gate::Keep;
    if (q.stopped) return Gate::Take;  // answered at once: not run
    // The firmware is asked where it is: nothing is translated before it answers.
    if (position_ == Position::Asking) return Gate::Wait;
    if (q.firmware && (!q.firmware_ready || q.queued >= q.queue_lines)) return Gate::Wait;
    return Gate::Take;
}

bool ServeSteps::ask_position() {
    // Nothing of a sender's is translated before the answer: a move translated from an assumed
    // position (the machine's home) can run far from where the sender meant.
    if (holding_) return false;
    position_ = Position::Asking;
    return true;
}

void ServeSteps::position_unanswered() {
    if (position_ != Position::Asking) return;
    position_ = Position::Unknown;
    position_why_ = "the firmware did not answer M114 with a position";
}

void ServeSteps::position_read(const std::vector<double>* q, std::optional<double> e, const std::string& why) {
    if (q) {
        translator_->place_at(*q, e, kReportResolution);
        position_ = Position::Known;
    } else {
        position_ = Position::Unknown;
        position_why_ = "the firmware's M114 answer could not be read: " + why;
    }
}

void ServeSteps::position_lost(const std::string& why) {
    position_ = Position::Unknown;
    position_why_ = "the firmware stopped: " + why;
}

}  // namespace xlate5
