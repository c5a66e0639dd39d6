// SPDX-License-Identifier: GPL-3.0-or-later
#include "daemon/virtual_printer.hpp"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <spdlog/spdlog.h>

#include "daemon/line_protocol.hpp"
#include "translators/error.hpp"

namespace xlate5 {
namespace {

using Clock = std::chrono::steady_clock;

Clock::duration ms(double v) { return std::chrono::microseconds(std::int64_t(v * 1000)); }

bool is_move(const proto::Code& c) {
    return c.letter == 'G' && (c.code10 == 0 || c.code10 == 10 || c.code10 == 20 || c.code10 == 30);
}

// The commands the personality knows; anything else gets Marlin's "Unknown command".
bool known(const proto::Code& c, bool reprap) {
    if (c.letter == 'T') return true;
    if (c.letter == 'G') {
        static const int g[] = {0, 1, 2, 3, 4, 10, 11, 17, 18, 19, 20, 21, 28, 29, 90, 91, 92, 94};
        for (int v : g)
            if (c.code10 == v * 10) return true;
        return reprap && c.code10 == 930;  // G93 inverse time: RepRapFirmware only
    }
    if (c.letter == 'M') {
        static const int m[] = {0, 1, 17, 18, 73, 82, 83, 84, 104, 105, 106, 107, 108, 109, 110, 112, 114, 115, 117, 118,
                                119, 140, 155, 190, 201, 203, 204, 205, 220, 221, 400, 410, 500, 501, 503, 999};
        for (int v : m)
            if (c.code10 == v * 10) return true;
        return reprap && (c.code10 == 4090 || c.code10 == 5840);
    }
    return false;
}

bool is_slow(const proto::Code& c) {
    return c.is('G', 28) || c.is('G', 4) || c.is('M', 109) || c.is('M', 190) || c.is('M', 400);
}

constexpr double kStepsPerMm = 80;  // for M114's "Count" words only

constexpr std::string_view kStopped =
    "Printer stopped due to errors. Fix the error and use M999 to restart. (Temperature is reset. Set it after restarting)";

}  // namespace

VirtualPrinter::VirtualPrinter(asio::io_context& io, int master_fd, SimOptions options)
    : opt_(std::move(options)), rng_(opt_.faults.seed), run_timer_(io), wire_timer_(io), busy_timer_(io), usb_timer_(io) {
    link_ = std::make_shared<DescriptorLink>(asio::posix::stream_descriptor(io, master_fd), "virtual printer");
    link_->eio_is_transient = true;  // xlate5 may close and reopen its end
    pos_.assign(opt_.axes.size() + 1, 0.0);
    if (!opt_.record_path.empty()) {
        // Emptied once, then written in append mode (O_APPEND): every write lands at the file's
        // end, so a file truncated meanwhile (a user's "> file", an instance restarted on it)
        // never gets a hole of NUL bytes where a private write offset would have left one.
        record_.open(opt_.record_path, std::ios::trunc);
        record_.close();
        record_.open(opt_.record_path, std::ios::app);
        if (!record_) throw IoError("sim.record: cannot write " + opt_.record_path);
    }
}

VirtualPrinter::~VirtualPrinter() { link_->close(); }

void VirtualPrinter::start() {
    // Weak: the link must not keep its owner alive (the record file is flushed when the
    // printer goes away); the same guard as every other handler of the service.
    std::weak_ptr<VirtualPrinter> weak = shared_from_this();
    if (opt_.baud > 0)
        link_->on_bytes = [weak](std::size_t n) {
            if (auto self = weak.lock()) self->on_bytes(n);
        };
    link_->start([weak](std::string_view line) {
        if (auto self = weak.lock()) self->on_line(line);
    }, [](const std::string&) {});
    boot();
}

void VirtualPrinter::boot() {
    checker_.set_last_line(0);
    rx_.clear();
    line_.clear();
    ring_.clear();
    planner_.clear();
    front_ready_.reset();
    processing_ = false;
    halted_ = stopped_ = false;
    relative_ = relative_e_ = false;
    // A reset forgets the position: the axes count from where they were at power-up.
    pos_.assign(opt_.axes.size() + 1, 0.0);
    for (std::size_t i = 0; i < opt_.start.size() && i < opt_.axes.size(); ++i) pos_[i] = opt_.start[i];
    run_timer_.cancel();
    busy_timer_.cancel();
    running_ = false;
    if (opt_.faults.greeting_resend) {
        // Still the number of a print before: the host's first numbered line is out of sequence.
        checker_.set_last_line(1000);
        stale_resend_due_ = true;
    }
    if (opt_.klipper) {
        // klippy's pty says nothing until written to; its axes start where the machine is.
        klast_.clear();
        kbase_.clear();
        for (std::size_t i = 0; i < opt_.start.size() && i < opt_.axes.size(); ++i)
            if (std::string("XYZ").find(opt_.axes[i]) != std::string::npos) klast_[opt_.axes[i]] = opt_.start[i];
        khomed_ = opt_.klipper_homed;
        kshutdown_ = false;
        kregistered_.clear();
        return;
    }
    reply("start");
    reply(opt_.reprap ? "RepRapFirmware (virtual, xlate5) started" : "echo:Marlin 2.1.2 (virtual printer, xlate5)");
}

void VirtualPrinter::unplug() {
    unplugged_ = true;
    run_timer_.cancel();
    wire_timer_.cancel();
    busy_timer_.cancel();
    usb_timer_.cancel();
    link_->close();
}

void VirtualPrinter::halt(const std::string& why) {
    halted_ = true;
    ring_.clear();
    front_ready_.reset();
    processing_ = false;
    rx_.clear();
    line_.clear();
    if (!why.empty()) reply(why);
    reply("Error:Printer halted. kill() called!");
}

void VirtualPrinter::reply(std::string line) {
    if (unplugged_) return;
    if (opt_.faults.garble_reply > 0 && uni_(rng_) < opt_.faults.garble_reply && !line.empty()) {
        std::uniform_int_distribution<std::size_t> at(0, line.size() - 1);
        std::uniform_int_distribution<int> bit(0, 6);
        line[at(rng_)] ^= char(1 << bit(rng_));  // "ok" may become "oo", "Resend: 41" "Resend: 45"
        ++stats_.garbled;
    }
    if (line.rfind("ok", 0) == 0) last_ok_ = Clock::now();
    line += '\n';
    link_->send(line);
}

void VirtualPrinter::on_line(std::string_view raw) {
    if (unplugged_) return;
    if (opt_.klipper) return klipper_line(std::string(raw));
    std::string line(raw);
    auto& f = opt_.faults;
    // M112 is acted on by the emergency parser as its bytes arrive, ahead of everything queued.
    if (!opt_.reprap && !halted_ && proto::command_code(proto::strip_comment(proto::parse_received(line).command)).is('M', 112)) {
        if (opt_.keep_executed) executed_.push_back("M112");
        if (record_.is_open()) record_ << "M112\n";
        halt("echo:M112 Shutdown");
        return;
    }
    // One fault a line at most: two can cancel in an XOR checksum (bit 5 flipped in one byte and
    // a space lost change it by the same 0x20), and no host can see that on Marlin's protocol.
    bool damaged = false;
    if (f.corrupt > 0 && !line.empty() && uni_(rng_) < f.corrupt) {
        std::uniform_int_distribution<std::size_t> at(0, line.size() - 1);
        std::uniform_int_distribution<int> bit(0, 6);
        line[at(rng_)] ^= char(1 << bit(rng_));
        ++stats_.corrupted;
        damaged = true;
    }
    bool newline = true;
    if (!damaged && f.drop > 0 && !line.empty() && uni_(rng_) < f.drop) {
        // One byte lost, or the newline (a single lost byte always changes an XOR checksum).
        std::uniform_int_distribution<std::size_t> at(0, line.size());
        const auto a = at(rng_);
        ++stats_.corrupted;
        if (a == line.size()) newline = false;
        else line.erase(a, 1);
    }
    if (f.lose_newline > 0 && newline && uni_(rng_) < f.lose_newline) {
        newline = false;
        ++stats_.lost_newlines;
    }
    if (newline) line += '\n';
    if (opt_.baud <= 0) {
        arrive(line);
        return;
    }
    // The wire: a line is there once its last byte has crossed (on_bytes timed every byte as it
    // came from the host: the first part of a line sent in two parts crosses while the host waits).
    const std::uint64_t end = link_->line_end();
    while (!chunks_.empty() && chunks_.front().end < end) chunks_.pop_front();
    const auto at = chunks_.empty() ? Clock::now() : chunks_.front().done - wire_time(chunks_.front().end - end);
    wire_.emplace_back(at, std::move(line));
    pump_wire();
}

Clock::duration VirtualPrinter::wire_time(std::uint64_t bytes) const {
    // Ten bits a byte (start, 8 data, stop).
    return std::chrono::nanoseconds(std::int64_t(double(bytes) * 1e10 / double(opt_.baud)));
}

void VirtualPrinter::on_bytes(std::size_t n) {
    // Bytes cross at baud/10 a second, in the order they came, starting when they came or when
    // the wire is free.
    const auto now = Clock::now();
    if (raw_bytes_ > 0 && wire_free_ < now && on_gap_) on_gap_(wire_free_, now, bytes_at_);
    bytes_at_ = now;
    wire_free_ = std::max(wire_free_, now) + wire_time(n);
    raw_bytes_ += n;
    chunks_.push_back({raw_bytes_, wire_free_});
    if (chunks_.size() > 4096) chunks_.pop_front();  // reads with no line end among them: memory stays bounded
}

void VirtualPrinter::pump_wire() {
    if (wire_.empty() || wire_armed_) return;
    wire_armed_ = true;
    std::weak_ptr<VirtualPrinter> weak = shared_from_this();
    wire_timer_.expires_at(wire_.front().first);
    wire_timer_.async_wait([weak](boost::system::error_code ec) {
        auto self = weak.lock();
        if (!self) return;
        self->wire_armed_ = false;
        if (ec || self->unplugged_) return;
        const auto t = Clock::now();
        while (!self->wire_.empty() && self->wire_.front().first <= t) {
            const std::string l = std::move(self->wire_.front().second);
            self->wire_.pop_front();
            self->arrive(l);
        }
        self->pump_wire();
    });
}

void VirtualPrinter::arrive(const std::string& bytes) {
    if (halted_ || unplugged_) return;
    stats_.bytes += bytes.size();
    // The serial receive buffer: what does not fit is lost.
    const std::size_t room = opt_.rx_size > rx_.size() ? opt_.rx_size - rx_.size() : 0;
    rx_.append(bytes, 0, std::min(room, bytes.size()));
    if (bytes.size() > room) stats_.overflow_bytes += bytes.size() - room;
    schedule();
}

void VirtualPrinter::schedule() {
    // The firmware's main loop reads the receive buffer later, not byte by byte as it arrives:
    // everything that came in one burst is in the buffer together (and flushed together).
    if (scheduled_) return;
    scheduled_ = true;
    std::weak_ptr<VirtualPrinter> weak = shared_from_this();
    auto loop = [weak](boost::system::error_code ec = {}) {
        auto self = weak.lock();
        if (!self || ec) return;
        self->scheduled_ = false;
        if (!self->processing_) self->read_serial();  // a main loop busy with a command reads nothing
        self->run_queue();
    };
    if (opt_.usb && opt_.baud <= 0) {
        usb_timer_.expires_after(std::chrono::milliseconds(1));
        usb_timer_.async_wait(loop);
    } else {
        asio::post(link_->stream_executor(), [loop] { loop(); });
    }
}

void VirtualPrinter::read_serial() {
    // Marlin's get_serial_commands: read while the command buffer has room.
    while (!halted_ && !unplugged_ && int(ring_.size()) < opt_.buffer && !rx_.empty()) {
        const char c = rx_.front();
        rx_.erase(0, 1);
        if (c == '\n' || c == '\r') {
            if (!line_.empty()) {
                std::string l;
                l.swap(line_);
                process(l);
            }
            continue;
        }
        line_ += c;
        if (line_.size() >= opt_.max_line - 1) {
            // MAX_CMD_SIZE - 1 characters: the line ends here, the rest is read as a new line.
            ++stats_.cut_lines;
            std::string l;
            l.swap(line_);
            process(l);
        }
    }
}

void VirtualPrinter::refuse(std::string_view why) {
    ++stats_.refused;
    reply(checker_.error_line(why));
    // Marlin empties the whole receive buffer: every line received but not yet read vanishes.
    stats_.flushed_bytes += rx_.size() + line_.size();
    rx_.clear();
    line_.clear();
    reply(checker_.resend_line());
    if (!opt_.faults.no_ok_after_resend) reply("ok");
}

void VirtualPrinter::process(const std::string& line) {
    ++stats_.received;
    if (stale_resend_due_) {
        // The firmware answers the first line with the old number it still holds.
        stale_resend_due_ = false;
        const auto r = proto::parse_received(line);
        if (r.number && !proto::command_code(proto::strip_comment(r.command)).is('M', 110)) {
            refuse(proto::kErrLineNumber);
            return;
        }
        reply(checker_.error_line(proto::kErrLineNumber));
        reply(checker_.resend_line());
        reply("ok");
    }
    const auto parsed = proto::parse_received(line);
    const std::string command = proto::strip_comment(parsed.command);
    const auto code = proto::command_code(command);
    if (code.is('M', 110) && parsed.number) {
        // A host greeting again: oks of earlier lines may still be on their way.
        if (greeted_once_)
            for (std::uint64_t i = 0; i < opt_.faults.stale_oks; ++i) reply("ok");
        greeted_once_ = true;
    }
    if (opt_.reprap) {
        // RepRapFirmware: a numbered line must carry a checksum, and any checksum must be right, or the line is dropped without a word.
        if ((parsed.number && !parsed.has_checksum) || !parsed.checksum_ok) {
            ++stats_.dropped;
            return;
        }
    } else {
        const auto v = checker_.check(line);
        if (v.verdict == proto::LineChecker::Verdict::Duplicate) {
            ++stats_.duplicates;  // taken for a copy of a line already in transit: no reply at all
            return;
        }
        if (v.verdict == proto::LineChecker::Verdict::Refuse) return refuse(v.why);
        if (opt_.faults.spurious_resend > 0 && parsed.number && !code.is('M', 110) && uni_(rng_) < opt_.faults.spurious_resend) {
            checker_.set_last_line(*parsed.number - 1);
            return refuse(proto::kErrChecksumMismatch);
        }
    }
    if (command.empty()) return;
    ring_.push_back({command, parsed.number.value_or(-1)});
}

void VirtualPrinter::run_queue() {
    if (running_) return;
    std::weak_ptr<VirtualPrinter> weak = shared_from_this();
    const auto wait = [&](asio::steady_timer& t, Clock::time_point until) {
        running_ = true;
        t.expires_at(until);
        t.async_wait([weak](boost::system::error_code ec) {
            auto self = weak.lock();
            if (!self) return;
            self->running_ = false;
            if (!ec) self->run_queue();
        });
    };
    while (!halted_ && !unplugged_) {
        read_serial();
        if (ring_.empty()) return;
        const auto now = Clock::now();
        if (opt_.faults.command_ms > 0) {
            // The command in front is parsed and queued first; its ok waits for that.
            if (!front_ready_) front_ready_ = now + ms(opt_.faults.command_ms);
            processing_ = now < *front_ready_;
            if (processing_) {
                wait(run_timer_, *front_ready_);
                return;
            }
        }
        const auto code = proto::command_code(ring_.front().text);
        if (is_move(code) && !stopped_) {
            while (!planner_.empty() && planner_.front() <= now) planner_.pop_front();
            if (int(planner_.size()) >= opt_.planner) {
                // A full planner: the command waits for a slot, and so does its ok. Marlin's
                // keepalive runs meanwhile (the command is in its handler).
                if (blocked_since_ == Clock::time_point{}) blocked_since_ = last_keepalive_ = now;
                if (!opt_.faults.quiet_planner && !opt_.reprap && now - last_keepalive_ >= ms(opt_.faults.busy_interval * 1000)) {
                    reply("echo:busy: processing");
                    last_keepalive_ = now;
                }
                wait(run_timer_, std::min(planner_.front(), last_keepalive_ + ms(opt_.faults.busy_interval * 1000)));
                return;
            }
            blocked_since_ = {};
            const auto begin = planner_.empty() ? now : std::max(now, planner_.back());
            planner_.push_back(begin + ms(opt_.faults.move_ms));
        }
        // A long wait: a random busy period on a move, or a slow command (homing, heating,
        // dwelling). Marlin sends keepalives meanwhile; RepRapFirmware says nothing.
        double hold = 0;
        if (is_move(code) && opt_.faults.busy > 0 && uni_(rng_) < opt_.faults.busy) hold = opt_.faults.busy_seconds;
        if (opt_.faults.slow_seconds > 0 && is_slow(code)) hold = opt_.faults.slow_seconds;
        if (hold > 0) {
            const auto until = now + ms(hold * 1000);
            running_ = true;
            auto tick = std::make_shared<std::function<void()>>();
            std::weak_ptr<std::function<void()>> loop = tick;
            *tick = [weak, until, loop]() {
                auto self = weak.lock();
                auto again = loop.lock();
                if (!self || !again) return;
                if (self->halted_ || self->unplugged_) { self->running_ = false; return; }
                if (Clock::now() >= until) {
                    self->running_ = false;
                    if (self->ring_.empty()) return;
                    const auto c = self->ring_.front();
                    self->ring_.pop_front();
                    self->front_ready_.reset();
                    self->execute(c);
                    self->run_queue();
                    return;
                }
                if (!self->opt_.reprap) self->reply("echo:busy: processing");
                self->busy_timer_.expires_after(std::min(ms(self->opt_.faults.busy_interval * 1000), until - Clock::now()));
                self->busy_timer_.async_wait([again](boost::system::error_code ec) { if (!ec) (*again)(); });
            };
            busy_timer_.expires_after(std::min(ms(opt_.faults.busy_interval * 1000), until - now));
            busy_timer_.async_wait([tick](boost::system::error_code ec) { if (!ec) (*tick)(); });
            return;
        }
        const auto c = ring_.front();
        ring_.pop_front();
        front_ready_.reset();
        execute(c);
    }
}

std::string VirtualPrinter::position_report() const {
    std::string s, count = " Count";
    char buf[64];
    for (std::size_t i = 0; i < opt_.axes.size(); ++i) {
        std::snprintf(buf, sizeof buf, "%s%c:%.2f", i ? " " : "", opt_.axes[i], pos_[i]);
        s += buf;
        std::snprintf(buf, sizeof buf, " %c:%ld", opt_.axes[i], long(std::lround(pos_[i] * kStepsPerMm)));
        count += buf;
    }
    std::snprintf(buf, sizeof buf, " E:%.2f", pos_.back());
    return s + buf + count;
}

void VirtualPrinter::execute(const Command& c) {
    const auto code = proto::command_code(c.text);
    std::string ok = "ok";
    const bool unknown = !code.letter || !known(code, opt_.reprap);
    if (stopped_ && is_move(code)) {
        // Stopped: moves are refused (and not run) until M999.
        reply("Error:" + std::string(kStopped));
    } else if (!unknown) {
        // Executed: what the firmware acted on (an unknown command is only echoed).
        ++stats_.executed;
        if (opt_.keep_executed) executed_.push_back(c.text);
        if (record_.is_open()) record_ << c.text << '\n';
    }
    if ((stopped_ && is_move(code)) || unknown) {
        if (unknown) reply("echo:Unknown command: \"" + c.text.substr(0, c.text.find(' ')) + "\"");
    } else if (code.is('G', 0) || code.is('G', 1) || code.is('G', 92)) {
        // The position for M114, as of the commands run so far: G92 sets, moves go to absolute
        // words or by relative ones (G91; M83 for E).
        const bool set = code.is('G', 92);
        for (std::size_t i = 0; i < c.text.size(); ++i) {
            const char l = c.text[i];
            if (i == 0 || c.text[i - 1] != ' ') continue;
            const double v = std::strtod(c.text.c_str() + i + 1, nullptr);
            const auto p = opt_.axes.find(l);
            if (p != std::string::npos) pos_[p] = (!set && relative_ ? pos_[p] : 0.0) + v;
            if (l == 'E') pos_.back() = (!set && relative_e_ ? pos_.back() : 0.0) + v;
        }
    } else if (code.is('G', 90) || code.is('G', 91)) {
        relative_ = relative_e_ = code.is('G', 91);  // Marlin: G90/G91 set E's mode too
    } else if (code.is('M', 82) || code.is('M', 83)) {
        relative_e_ = code.is('M', 83);
    } else if (code.is('M', 110) && !opt_.reprap) {
        // gcode/host/M110.cpp: the number is set again as the command runs.
        if (const auto n = proto::m110_line(c.text)) checker_.set_last_line(*n);
    } else if (code.is('M', 115)) {
        if (!opt_.firmware_name.empty()) {
            reply("FIRMWARE_NAME:" + opt_.firmware_name);
        } else if (opt_.reprap) {
            reply("FIRMWARE_NAME: RepRapFirmware for Duet 3 (virtual, xlate5) FIRMWARE_VERSION: 3.5.0 ELECTRONICS: virtual");
        } else {
            reply("FIRMWARE_NAME:Marlin 2.1.2 (virtual printer, xlate5) SOURCE_CODE_URL:local PROTOCOL_VERSION:1.0 "
                  "MACHINE_TYPE:virtual KINEMATICS:Cartesian EXTRUDER_COUNT:1 AXIS_COUNT:" + std::to_string(opt_.axes.size()));
            reply("Cap:SERIAL_XON_XOFF:0");
            reply("Cap:EEPROM:0");
            reply("Cap:AUTOREPORT_TEMP:1");
            reply("Cap:AUTOREPORT_POS:0");
            reply("Cap:EMERGENCY_PARSER:1");
            reply("Cap:HOST_ACTION_COMMANDS:0");
        }
    } else if (code.is('M', 114)) {
        reply(opt_.faults.junk_position ? "X:abc Y:0.00 E:0.00 Count X:0 Y:0" : position_report());
    } else if (code.is('M', 105)) {
        ok = "ok T:21.50 /0.00 B:20.10 /0.00 @:0 B@:0";
    } else if (code.is('M', 999) && !opt_.reprap) {
        // Marlin: running again, and the host is asked to go on from the line after the last one.
        stopped_ = false;
        reply(checker_.resend_line());
    }
    if (opt_.advanced_ok && !opt_.reprap && ok == "ok") {
        // The N is the command's own, when it had one (Marlin copies it from the buffer).
        const int planner_free = opt_.planner - int(planner_.size());
        if (c.n >= 0) ok += " N" + std::to_string(c.n);
        ok += " P" + std::to_string(std::max(0, planner_free)) + " B" + std::to_string(std::max(0, opt_.buffer - 1 - int(ring_.size())));
    }
    if (opt_.faults.lose_ok > 0 && uni_(rng_) < opt_.faults.lose_ok) ++stats_.lost_oks;
    else reply(ok);
    const auto& f = opt_.faults;
    if (f.unplug_after && stats_.executed == f.unplug_after) {
        unplug();
    } else if (f.kill_after && stats_.executed == f.kill_after) {
        halt("echo:Homing Failed");
    } else if (f.stop_after && stats_.executed == f.stop_after && !stopped_) {
        stopped_ = true;
        reply("Error:" + std::string(kStopped));
    } else if ((f.reset_after && stats_.executed == f.reset_after) || (f.reset_every && stats_.executed % f.reset_every == 0)) {
        ++stats_.resets;
        boot();
    }
}

}  // namespace xlate5
