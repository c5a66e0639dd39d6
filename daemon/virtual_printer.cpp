#include "daemon/virtual_printer.hpp"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <spdlog/spdlog.h>

#include "daemon/line_protocol.hpp"

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

}  // namespace

VirtualPrinter::VirtualPrinter(asio::io_context& io, int master_fd, SimOptions options)
    : opt_(std::move(options)), rng_(opt_.faults.seed), run_timer_(io), wire_timer_(io), busy_timer_(io) {
    link_ = std::make_shared<DescriptorLink>(asio::posix::stream_descriptor(io, master_fd), "virtual printer");
    link_->eio_is_transient = true;  // xlate5 may close and reopen its end
    link_->max_line = opt_.max_line;  // a longer line is cut, as in the firmware's buffer
    pos_.assign(opt_.axes.size() + 1, 0.0);
    if (!opt_.record_path.empty()) record_.open(opt_.record_path, std::ios::trunc);
}

VirtualPrinter::~VirtualPrinter() { link_->close(); }

void VirtualPrinter::start() {
    // A weak reference: the link must not keep its owner alive (the record file is flushed when
    // the printer goes away).
    std::weak_ptr<VirtualPrinter> weak = shared_from_this();
    link_->start([weak](std::string_view line) {
        if (auto self = weak.lock()) self->on_line(line);
    }, [](const std::string&) {});
    boot();
}

void VirtualPrinter::boot() {
    last_n_ = 0;
    buffer_.clear();
    planner_.clear();
    halted_ = false;
    run_timer_.cancel();
    busy_timer_.cancel();
    running_ = false;
    reply("start");
    reply(opt_.reprap ? "RepRapFirmware (virtual, xlate5) started" : "echo:Marlin 2.1.2 (virtual printer, xlate5)");
}

void VirtualPrinter::unplug() {
    unplugged_ = true;
    run_timer_.cancel();
    wire_timer_.cancel();
    busy_timer_.cancel();
    link_->close();
}

void VirtualPrinter::reply(std::string line) {
    if (unplugged_) return;
    if (opt_.faults.garble_reply > 0 && uni_(rng_) < opt_.faults.garble_reply && !line.empty()) {
        std::uniform_int_distribution<std::size_t> at(0, line.size() - 1);
        line[at(rng_)] ^= 0x20;  // e.g. "ok" becomes "oK" or "Ok"... and "Resend" something else
        ++stats_.garbled;
    }
    line += '\n';
    link_->send(line);
}

void VirtualPrinter::on_line(std::string_view raw) {
    if (unplugged_) return;
    stats_.bytes += raw.size() + 1;
    std::string line(raw);
    auto& f = opt_.faults;
    if (f.corrupt > 0 && !line.empty() && uni_(rng_) < f.corrupt) {
        std::uniform_int_distribution<std::size_t> at(0, line.size() - 1);
        std::uniform_int_distribution<int> bit(0, 6);
        line[at(rng_)] ^= char(1 << bit(rng_));
        ++stats_.corrupted;
    }
    if (!carry_.empty()) {
        line = carry_ + line;  // the newline before this line was lost: the two arrive as one
        carry_.clear();
    }
    if (f.drop > 0 && !line.empty() && uni_(rng_) < f.drop) {
        // One byte lost (a single lost byte always changes an XOR checksum; several can cancel
        // out, which no XOR-checked firmware can notice), or the newline.
        std::uniform_int_distribution<std::size_t> at(0, line.size());
        const auto a = at(rng_);
        ++stats_.corrupted;
        if (a == line.size()) {
            carry_ = line;
            return;
        }
        line.erase(a, 1);
    }
    if (opt_.baud <= 0) {
        accept(line);
        return;
    }
    // The wire: a line is complete only after its bytes have crossed at baud/10 bytes per second.
    const auto now = Clock::now();
    if (wire_free_ < now) wire_free_ = now;
    wire_free_ += std::chrono::microseconds(std::int64_t((line.size() + 1) * 10.0 * 1e6 / opt_.baud));
    wire_.emplace_back(wire_free_, std::move(line));
    pump_wire();
}

void VirtualPrinter::pump_wire() {
    if (wire_.empty() || wire_armed_) return;
    wire_armed_ = true;
    auto self = shared_from_this();
    wire_timer_.expires_at(wire_.front().first);
    wire_timer_.async_wait([this, self](boost::system::error_code ec) {
        wire_armed_ = false;
        if (ec || unplugged_) return;
        const auto t = Clock::now();
        while (!wire_.empty() && wire_.front().first <= t) {
            const std::string l = std::move(wire_.front().second);
            wire_.pop_front();
            accept(l);
        }
        pump_wire();
    });
}

void VirtualPrinter::refuse(const char* why) {
    ++stats_.refused;
    reply(std::string("Error:") + why + ", Last Line: " + std::to_string(last_n_));
    reply("Resend: " + std::to_string(last_n_ + 1));
    if (!opt_.faults.no_ok_after_resend) reply("ok");
}

void VirtualPrinter::accept(std::string_view line) {
    if (halted_ || unplugged_) return;
    ++stats_.received;
    const auto r = proto::parse_received(line);
    const std::string command = proto::strip_comment(r.command);
    if (command.empty() && !r.number) return;
    const auto code = proto::command_code(command);
    // The emergency parser acts on these as the bytes arrive, ahead of the buffer.
    if (code.is('M', 112)) {
        if (opt_.keep_executed) executed_.push_back("M112");
        if (record_.is_open()) record_ << "M112\n";
        halted_ = true;
        reply("Error:Printer halted. kill() called!");
        return;
    }
    if (r.number) {
        const bool checked = r.has_checksum && r.checksum_ok;
        if (opt_.reprap) {
            if (!checked) {  // RepRapFirmware drops it without a word: the host must time out
                ++stats_.dropped;
                return;
            }
        } else {
            if (!r.has_checksum) return refuse("No Checksum with line number");
            if (!r.checksum_ok) return refuse("checksum mismatch");
            if (!code.is('M', 110) && *r.number != last_n_ + 1) return refuse("Line Number is not Last Line Number+1");
            if (opt_.faults.spurious_resend > 0 && !code.is('M', 110) && uni_(rng_) < opt_.faults.spurious_resend)
                return refuse("checksum mismatch");
        }
        last_n_ = *r.number;
    }
    if (code.is('M', 110))
        if (const auto n = proto::m110_line(command)) last_n_ = *n;
    if (!r.number && r.has_checksum) {
        if (!r.checksum_ok || !opt_.reprap) {
            // A damaged N: Marlin refuses it, RepRapFirmware drops it (the checksum fails).
            if (opt_.reprap) {
                ++stats_.dropped;
                return;
            }
            return refuse("No Line Number with checksum");
        }
    }
    buffer_.push_back({command, r.number.value_or(-1)});
    run_queue();
}

void VirtualPrinter::run_queue() {
    if (running_) return;
    auto self = shared_from_this();
    while (!buffer_.empty() && !halted_ && !unplugged_) {
        const auto now = Clock::now();
        const auto code = proto::command_code(buffer_.front().text);
        if (is_move(code)) {
            while (!planner_.empty() && planner_.front() <= now) planner_.pop_front();
            if (int(planner_.size()) >= opt_.planner) {
                // Slow planner: the command waits for a slot, and so does its ok.
                running_ = true;
                run_timer_.expires_at(planner_.front());
                run_timer_.async_wait([this, self](boost::system::error_code ec) {
                    running_ = false;
                    if (!ec) run_queue();
                });
                return;
            }
            const auto begin = planner_.empty() ? now : std::max(now, planner_.back());
            planner_.push_back(begin + ms(opt_.faults.move_ms));
        }
        // A long wait: a random busy period on a move, or a slow command (homing, heating,
        // dwelling). Marlin sends keepalives meanwhile; RepRapFirmware says nothing.
        double hold = 0;
        if (is_move(code) && opt_.faults.busy > 0 && uni_(rng_) < opt_.faults.busy) hold = opt_.faults.busy_seconds;
        if (opt_.faults.slow_seconds > 0 && (code.is('G', 28) || code.is('G', 4) || code.is('M', 109) || code.is('M', 190) || code.is('M', 400)))
            hold = opt_.faults.slow_seconds;
        if (hold > 0) {
            {
                running_ = true;
                const auto until = now + ms(hold * 1000);
                const bool keepalives = !opt_.reprap;
                // The keepalive loop holds itself only through the pending timer's handler (a
                // weak self-reference), so it goes away when the loop ends.
                auto keepalive = std::make_shared<std::function<void()>>();
                std::weak_ptr<std::function<void()>> loop = keepalive;
                *keepalive = [this, self, until, loop, keepalives]() {
                    if (halted_ || unplugged_) { running_ = false; return; }
                    if (Clock::now() >= until) {
                        running_ = false;
                        const auto c = buffer_.front();
                        buffer_.pop_front();
                        execute(c);
                        run_queue();
                        return;
                    }
                    if (keepalives) reply("echo:busy: processing");
                    busy_timer_.expires_after(ms(opt_.faults.busy_interval * 1000));
                    busy_timer_.async_wait([again = loop.lock()](boost::system::error_code ec) { if (!ec && again) (*again)(); });
                };
                busy_timer_.expires_after(ms(opt_.faults.busy_interval * 1000));
                busy_timer_.async_wait([keepalive](boost::system::error_code ec) { if (!ec) (*keepalive)(); });
                return;
            }
        }
        const auto c = buffer_.front();
        buffer_.pop_front();
        execute(c);
    }
}

std::string VirtualPrinter::position_report() const {
    std::string s, count = " Count";
    char buf[64];
    for (std::size_t i = 0; i < opt_.axes.size(); ++i) {
        std::snprintf(buf, sizeof buf, "%s%c:%.2f", i ? " " : "", opt_.axes[i], pos_[i]);
        s += buf;
        std::snprintf(buf, sizeof buf, " %c:%ld", opt_.axes[i], long(std::lround(pos_[i] * 80)));
        count += buf;
    }
    std::snprintf(buf, sizeof buf, " E:%.2f", pos_.back());
    return s + buf + count;
}

void VirtualPrinter::execute(const Command& c) {
    ++stats_.executed;
    if (opt_.keep_executed) executed_.push_back(c.text);
    if (record_.is_open()) record_ << c.text << '\n';
    const auto code = proto::command_code(c.text);
    std::string ok = "ok";
    if (code.is('G', 0) || code.is('G', 1) || code.is('G', 92)) {
        // Track the position for M114 (absolute words only: xlate5 always sends absolute joints).
        for (std::size_t i = 0; i < c.text.size(); ++i) {
            const char l = c.text[i];
            if (i == 0 || c.text[i - 1] != ' ') continue;
            const auto p = opt_.axes.find(l);
            if (p != std::string::npos) pos_[p] = std::strtod(c.text.c_str() + i + 1, nullptr);
            if (l == 'E') pos_.back() = std::strtod(c.text.c_str() + i + 1, nullptr);
        }
    } else if (code.is('M', 115)) {
        if (opt_.reprap) {
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
        reply(position_report());
    } else if (code.is('M', 105)) {
        ok = "ok T:21.50 /0.00 B:20.10 /0.00 @:0 B@:0";
    } else if (code.letter && !known(code, opt_.reprap)) {
        reply("echo:Unknown command: \"" + c.text.substr(0, c.text.find(' ')) + "\"");
    }
    if (opt_.advanced_ok && !opt_.reprap && ok == "ok") {
        int planner_free = opt_.planner - int(planner_.size());
        ok += " N" + std::to_string(c.n < 0 ? last_n_ : c.n) + " P" + std::to_string(std::max(0, planner_free)) + " B" +
              std::to_string(std::max(0, opt_.buffer - 1 - int(buffer_.size())));
    }
    reply(ok);
    const auto& f = opt_.faults;
    if (f.unplug_after && stats_.executed == f.unplug_after) {
        unplug();
    } else if (f.kill_after && stats_.executed == f.kill_after) {
        halted_ = true;
        reply("echo:Homing Failed");
        reply("Error:Printer halted. kill() called!");
    } else if (f.reset_after && stats_.executed == f.reset_after) {
        ++stats_.resets;
        boot();
    }
}

}  // namespace xlate5
