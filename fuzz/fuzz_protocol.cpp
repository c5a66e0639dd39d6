// SPDX-License-Identifier: GPL-3.0-or-later
// Fuzz target: the firmware protocol core (FirmwareProtocol, no I/O) driven by a script of
// firmware replies, commands and a clock, as tests/test_protocol.cpp drives it. Stage: test
// harness; may call firmware_protocol and line_protocol.
//
// Input: byte 0 picks the options (bit 0: RepRapFirmware; bits 1-2: window 0..3; bit 3: a
// 48-byte line buffer instead of Marlin's 96), then one event a line, by its first character:
//   r<text>  the firmware replies <text>     e<text>  a command for the queue
//   t<d>     the clock passes d*10 ms (d a digit) and reaches the deadline if it is due
//   u<text>  M108/M410-like, ahead of the queue  x  M112   m  M999 (restart)   c  the port closes
//   anything else: the firmware replies the whole line.
// Besides the sanitizers, a finding is a line written longer than the firmware's buffer, or
// an Acked tag never given to enqueue.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <set>
#include <spdlog/spdlog.h>
#include <string>
#include <string_view>

#include "daemon/firmware_protocol.hpp"

using namespace xlate5;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    static const bool quiet = [] {
        spdlog::set_level(spdlog::level::off);
        return true;
    }();
    (void)quiet;
    if (size < 1) return 0;
    FirmwareOptions o;
    o.reprap = (data[0] & 1u) != 0;
    o.window = int((data[0] >> 1) & 3u);
    if (data[0] & 8u) o.max_line = 48;
    FirmwareProtocol p(o);
    using Clock = FirmwareProtocol::Clock;
    Clock::time_point now{};
    std::set<std::uint64_t> tags;
    std::uint64_t next_tag = 1;
    std::size_t events = 0;

    const auto check = [&] {
        for (const auto& a : p.take_actions()) {
            if (a.kind == FirmwareProtocol::Action::Kind::Write) {
                std::size_t begin = 0;
                while (begin < a.text.size()) {
                    std::size_t nl = a.text.find('\n', begin);
                    if (nl == std::string::npos) nl = a.text.size();
                    if (nl - begin + 1 > o.max_line) std::abort();  // never a line over the firmware's buffer
                    begin = nl + 1;
                }
            }
            if (a.kind == FirmwareProtocol::Action::Kind::Acked && a.tag != 0 && !tags.count(a.tag)) std::abort();
        }
    };

    p.open(now);
    check();
    const std::string_view text(reinterpret_cast<const char*>(data + 1), size - 1);
    for (std::size_t pos = 0; pos <= text.size() && events < 4000; ++events) {
        std::size_t end = text.find('\n', pos);
        if (end == std::string_view::npos) end = text.size();
        const std::string_view line = text.substr(pos, end - pos);
        pos = end + 1;
        const char k = line.empty() ? 'r' : line.front();
        const std::string_view rest = line.empty() ? line : line.substr(1);
        switch (k) {
        case 'r': p.on_line(rest, now); break;
        case 'e': {
            const std::string command(rest);
            if (command.empty() || !p.fits(command) || command.find('\n') != std::string::npos) break;
            std::uint64_t tag = 0;
            if (rest.size() % 3 == 0) tags.insert(tag = next_tag++);
            p.enqueue(command, tag, now);
            break;
        }
        case 't': {
            const int d = rest.empty() || rest.front() < '0' || rest.front() > '9' ? 10 : rest.front() - '0';
            now += std::chrono::milliseconds(10 * d);
            if (const auto dl = p.deadline(); dl && *dl <= now) p.on_time(now);
            break;
        }
        case 'u': {
            const std::string command(rest.substr(0, 40));
            if (command.find('\n') == std::string::npos) p.send_unnumbered(command, now);
            break;
        }
        case 'x': p.emergency_stop("M112", now); break;
        case 'm': p.restart(now); break;
        case 'c': p.port_closed("closed"); break;
        default: p.on_line(line, now); break;
        }
        check();
    }
    // Time runs out: every deadline is reached, as the timer would.
    for (int i = 0; i < 64; ++i) {
        const auto dl = p.deadline();
        if (!dl) break;
        now = std::max(now, *dl);
        p.on_time(now);
        check();
    }
    return 0;
}
