// SPDX-License-Identifier: GPL-3.0-or-later
// Benchmark (not a test): the whole chain, sender -> xlate5 serve -> virtual printer, on real
// pseudo-terminals in one process. Reports lines/s, how busy the firmware's link is kept when
// it is the bottleneck (does xlate5 ever starve it?), and the latency xlate5 adds per line: the
// sender's send-to-ok time through xlate5 of the lines sent while xlate5's queue had room (the
// rest wait for the link, by design), whose p99 bounds what xlate5 adds from above (what it adds
// lies inside the round trip); with the link unlimited, the same sender talking to the virtual
// printer directly as well, for context. The
// host's load average and CPU steal over the run are printed next to the figures: on a shared
// machine they explain most of the spread.
//   bench_service [lines=20000] [baud=0 (unlimited) | 115200 | 250000 ...] [machine=rw2] [rx_bytes=127]
//                 [travel_every=0 (none: the look-back holds full 2000-line windows) | N: a travel move every N lines]
//                 [command_ms=0: the firmware's time to parse and queue each command] [two_parts=1 | 0: lines wait whole]
// With a limited link it also counts the link's idle gaps (on the firmware's side of the wire)
// by what ended them: an ok the firmware wrote during the gap (split into the firmware's part,
// last byte to ok, and the round trip through xlate5, ok to the next byte), a line from the
// sender during the gap (xlate5 had nothing to send, or held it in the look-back window), an ok
// written while bytes were still crossing that xlate5 answered only after they had (a late
// wake-up), or none of these (a timer).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fcntl.h>
#include <fstream>
#include <functional>
#include <iterator>
#include <sstream>
#include <random>
#include <spdlog/spdlog.h>
#include <sys/resource.h>
#include <unistd.h>
#include <vector>

#include "daemon/line_protocol.hpp"
#include "daemon/link.hpp"
#include "daemon/ports.hpp"
#include "daemon/serve.hpp"
#include "translators/kinematics/kinematics.hpp"
#include "translators/pipeline/translator.hpp"

using namespace xlate5;
using Clock = std::chrono::steady_clock;

namespace {

// The print: start code, then short 5-axis moves, line i computed from i alone (the sender needs
// no copy of the file: the benchmark's own memory stays flat too).
constexpr std::size_t kStart = 4;
std::size_t travel_every = 0;  // 0: no travel moves (a vase-mode print: the look-back's window is always full)
std::string print_line(std::size_t i) {
    static const char* start[kStart] = {"G28", "G92 A-168", "G1 A0 B0 F3000", "M83"};
    if (i < kStart) return start[i];
    const double t = double(i) * 0.01;
    char buf[160];
    const bool travel = travel_every > 0 && i % travel_every == 0;  // a move without E: the look-back's next checkpoint
    std::snprintf(buf, sizeof buf, "G1 X%.3f Y%.3f Z10 A%.2f B%.2f%s F1800", 100 + 30 * std::cos(t), 100 + 30 * std::sin(t),
                  60 * std::sin(t * 0.3), 25 * std::sin(t * 0.7), travel ? "" : " E0.02");
    return buf;
}

// Send-to-ok times in 1 us buckets up to 100 ms: fixed memory.
struct Latency {
    std::vector<std::uint32_t> buckets = std::vector<std::uint32_t>(100000, 0);
    std::uint64_t count = 0;
    void add(double us) {
        ++buckets[std::min<std::size_t>(buckets.size() - 1, std::size_t(us))];
        ++count;
    }
    double percentile(double p) const {
        std::uint64_t seen = 0;
        for (std::size_t i = 0; i < buckets.size(); ++i)
            if ((seen += buckets[i]) > std::uint64_t(p * double(count))) return double(i);
        return double(buckets.size());
    }
};

// The host: load average, and CPU time stolen by the hypervisor (/proc/stat, all CPUs).
struct Host {
    std::uint64_t steal = 0, total = 0;
    static Host now() {
        Host h;
        std::ifstream f("/proc/stat");
        std::string cpu;
        f >> cpu;
        std::uint64_t v[10] = {};
        for (int i = 0; i < 10 && (f >> v[i]); ++i) h.total += i < 8 ? v[i] : 0;  // guest time is already in user
        h.steal = v[7];
        return h;
    }
    static std::string load() {
        std::ifstream f("/proc/loadavg");
        std::string a, b, c;
        f >> a >> b >> c;
        return a + " " + b + " " + c;
    }
};

// Ping-pong sender, numbered and checksummed (as printcore and OctoPrint send while printing).
struct Sender {
    std::shared_ptr<DescriptorLink> link;
    std::function<std::string(std::size_t)> line;
    std::size_t count, next = 0;
    std::int64_t resend = -1;
    Clock::time_point sent_at;
    Latency latency, with_room;  // every line; lines sent while xlate5's queue had room
    std::function<bool()> room;  // whether the queue had room when the line was sent
    bool had_room = true;
    bool done = false;

    Sender(asio::io_context& io, int fd, std::size_t n, std::function<std::string(std::size_t)> l) : line(std::move(l)), count(n) {
        make_raw(fd);
        link = std::make_shared<DescriptorLink>(asio::posix::stream_descriptor(io, fd), "bench sender");
        link->start([this](std::string_view r) { on_line(r); }, [](const std::string&) {});
    }
    void send() {
        if (next >= count) {
            done = true;
            return;
        }
        sent_at = Clock::now();
        had_room = !room || room();
        link->send(proto::numbered(std::int64_t(next) + 1, line(next)) + "\n");
    }
    void on_line(std::string_view r) {
        const auto c = proto::classify(r);
        if (c.kind == proto::ReplyKind::Resend) resend = c.resend_line;
        if (c.kind != proto::ReplyKind::Ok) return;
        const double us = std::chrono::duration<double, std::micro>(Clock::now() - sent_at).count();
        latency.add(us);
        // The first line waits for xlate5 to notice the sender (a closed pseudo-terminal is polled
        // every 100 ms): once per connection, not per line.
        if (had_room && next > 0) with_room.add(us);
        if (std::getenv("BENCH_SLOW") && us > 10000) std::fprintf(stderr, "slow ok: line %zu %.0f us room %d\n", next, us, int(had_room));
        if (resend > 0) next = std::size_t(resend - 1), resend = -1;
        else ++next;
        send();
    }
};

// The link's idle gaps, by what ended them, and by size.
struct Gaps {
    static constexpr double kEdges[] = {10e-6, 30e-6, 100e-6, 300e-6, 1e-3, 3e-3, 10e-3, 100e-3, 1.0};
    static constexpr std::size_t kBuckets = std::size(kEdges) + 1;
    enum Cause { Ok, LateOk, Sender, Other, kCauses };
    std::uint64_t count[kCauses] = {};
    double total[kCauses] = {};                  // seconds idle
    double firmware = 0, round_trip = 0;         // Ok: last byte -> ok; ok -> next byte (through xlate5)
    double sender = 0, xlate5 = 0;               // Sender: idle -> sender's line; the line -> its bytes
    std::uint64_t size_count[kBuckets] = {};
    double size_total[kBuckets] = {};
    double idle() const { return total[Ok] + total[LateOk] + total[Sender] + total[Other]; }
    void add(Cause c, double s) {
        ++count[c];
        total[c] += s;
        std::size_t b = 0;
        while (b < std::size(kEdges) && s >= kEdges[b]) ++b;
        ++size_count[b];
        size_total[b] += s;
    }
};

void print_gaps(const char* phase, const Gaps& g) {
    std::printf("  link idle, %s: %.4f s in %llu gaps; ended by an ok written during the gap %llu (%.4f s: firmware %.4f s,"
                " round trip through xlate5 %.4f s), by an ok written before it (xlate5's answer later than the bytes in flight)"
                " %llu (%.4f s), by a line from the sender %llu (%.4f s: idle until its latest line %.4f s, from that line to its bytes %.4f s), by none of these %llu (%.4f s)\n",
                phase, g.idle(), static_cast<unsigned long long>(g.count[0] + g.count[1] + g.count[2] + g.count[3]),
                static_cast<unsigned long long>(g.count[Gaps::Ok]), g.total[Gaps::Ok], g.firmware, g.round_trip,
                static_cast<unsigned long long>(g.count[Gaps::LateOk]), g.total[Gaps::LateOk],
                static_cast<unsigned long long>(g.count[Gaps::Sender]), g.total[Gaps::Sender], g.sender, g.xlate5,
                static_cast<unsigned long long>(g.count[Gaps::Other]), g.total[Gaps::Other]);
}

void print_sizes(const Gaps& g) {
    std::printf("  idle gaps by size (middle): ");
    for (std::size_t b = 0; b < Gaps::kBuckets; ++b) {
        if (!g.size_count[b]) continue;
        if (b < std::size(Gaps::kEdges)) std::printf("<%.0f us: %llu (%.4f s)  ", Gaps::kEdges[b] * 1e6, static_cast<unsigned long long>(g.size_count[b]), g.size_total[b]);
        else std::printf(">=1 s: %llu (%.4f s)  ", static_cast<unsigned long long>(g.size_count[b]), g.size_total[b]);
    }
    std::printf("\n");
}

bool run(asio::io_context& io, const std::function<bool()>& done, double seconds) {
    const auto end = Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(seconds));
    while (!done()) {
        if (Clock::now() > end) return false;
        io.run_for(std::chrono::milliseconds(20));
    }
    return true;
}

}  // namespace

int main(int argc, char** argv) {
    const std::size_t n = argc > 1 ? std::size_t(std::atol(argv[1])) : 20000;
    const int baud = argc > 2 ? std::atoi(argv[2]) : 0;
    const std::string machine_name = argc > 3 ? argv[3] : "rw2";
    const long rx_arg = argc > 4 ? std::atol(argv[4]) : 0;
    travel_every = argc > 5 ? std::size_t(std::max(0L, std::atol(argv[5]))) : 0;
    const double command_ms = argc > 6 ? std::atof(argv[6]) : 0;
    const bool two_parts = argc > 7 ? std::atoi(argv[7]) != 0 : true;
    if (!(command_ms >= 0 && command_ms <= 10000)) {
        std::fprintf(stderr, "bench_service: command_ms must be from 0 to 10000\n");
        return 2;
    }
    spdlog::set_level(spdlog::level::warn);
    std::setvbuf(stdout, nullptr, _IOLBF, 0);
    const std::size_t total = kStart + n;

    // Through xlate5.
    asio::io_context io;
    char dir[] = "/tmp/xlate5-bench-XXXXXX";
    if (!::mkdtemp(dir)) return 2;
    ServeConfig cfg;
    cfg.machine = machine_name;
    cfg.port = "sim";
    cfg.pty = std::string(dir) + "/printer";
    cfg.sim.baud = baud;
    cfg.firmware.boot_wait = 0.1;
    cfg.sim.faults.command_ms = command_ms;
    cfg.firmware.two_parts = two_parts;
    if (rx_arg >= 64 && rx_arg <= (1 << 20)) {
        cfg.firmware.rx_bytes = std::size_t(rx_arg);
        cfg.sim.rx_size = std::max(cfg.sim.rx_size, cfg.firmware.rx_bytes + 1);  // a board built with that buffer
    }
    const Machine machine = load_machine(machine_name);
    Assembly parts;
    assemble(io, cfg, machine, parts);
    run(io, [&] { return parts.service->firmware()->state() == FirmwareLink::State::Ready; }, 5);
    Sender sender(io, ::open(cfg.pty.c_str(), O_RDWR | O_NOCTTY | O_CLOEXEC), total, print_line);
    sender.room = [&] { return parts.service->firmware()->queued() < cfg.queue_lines; };
    const std::string load_before = Host::load();
    const Host host0 = Host::now();
    const auto t0 = Clock::now();
    Gaps phases[3];  // start (to a tenth of the lines), middle, end
    int phase = 0;
    parts.sim->on_wire_gap([&](Clock::time_point from, Clock::time_point to, Clock::time_point bytes_before) {
        from = std::max(from, t0);
        if (to <= from) return;
        const double s = std::chrono::duration<double>(to - from).count();
        Gaps& g = phases[phase];
        if (std::getenv("BENCH_GAPS") && s > 0.005)  // each long gap: where in the print, and xlate5's queue when it ended
            std::fprintf(stderr, "gap %.1f ms at sender line %zu, %.1f ms after the firmware's ok, %zu lines queued for the firmware\n", s * 1e3,
                         sender.next, std::chrono::duration<double, std::milli>(to - parts.sim->last_ok()).count(),
                         parts.service->firmware()->queued());
        const auto ok_at = parts.sim->last_ok();
        if (ok_at >= from) {
            g.add(Gaps::Ok, s);
            g.firmware += std::chrono::duration<double>(ok_at - from).count();
            g.round_trip += std::chrono::duration<double>(to - ok_at).count();
        } else if (sender.sent_at >= from) {
            g.add(Gaps::Sender, s);
            g.sender += std::chrono::duration<double>(sender.sent_at - from).count();
            g.xlate5 += std::chrono::duration<double>(to - sender.sent_at).count();
        } else if (ok_at > bytes_before) {
            g.add(Gaps::LateOk, s);  // the ok came while bytes were still crossing; xlate5 answered after they had
        } else {
            g.add(Gaps::Other, s);
        }
    });
    sender.send();
    // The link in the middle of the print (from a tenth of the lines to nine tenths), apart from
    // its start (the look-back holds the first window until it is decided) and its end (held
    // output goes after hold_seconds of silence from the sender): both happen once per print.
    run(io, [&] { return sender.next >= total / 10; }, 3600);
    const auto mid0 = std::make_pair(Clock::now(), parts.sim->stats().bytes);
    phase = 1;
    run(io, [&] { return sender.next >= total * 9 / 10; }, 3600);
    const auto mid1 = std::make_pair(Clock::now(), parts.sim->stats().bytes);
    phase = 2;
    const bool ok = run(io, [&] { return sender.done && parts.service->idle(); }, 3600);
    const auto t_end = Clock::now();
    const double seconds = std::chrono::duration<double>(t_end - t0).count();
    // The last idle stretch, after the last byte crossed, ends the run rather than a gap.
    const double tail = baud > 0 && parts.sim->wire_free() < t_end ? std::chrono::duration<double>(t_end - parts.sim->wire_free()).count() : 0;
    const Host host1 = Host::now();
    const double steal = host1.total > host0.total ? 100.0 * double(host1.steal - host0.steal) / double(host1.total - host0.total) : 0;
    const auto executed = parts.sim->stats().executed;
    const auto bytes = parts.sim->stats().bytes;
    const double wire_capacity = baud > 0 ? double(baud) / 10.0 * seconds : 0;  // bytes the link could carry
    std::printf("through xlate5 (%s, %s, receive-buffer budget %zu bytes, lines in two parts %s, firmware's time per command %.3f ms):\n",
                machine_name.c_str(), baud > 0 ? (std::to_string(baud) + " baud").c_str() : "unlimited link", cfg.firmware.rx_bytes,
                two_parts ? "on" : "off", command_ms);
    std::printf("  %zu sender lines in %.2f s: %.0f lines/s in, %.0f lines/s to the firmware (%llu executed)%s\n", total,
                seconds, double(total) / seconds, double(executed) / seconds, static_cast<unsigned long long>(executed),
                ok ? "" : "  (DID NOT FINISH)");
    if (baud > 0) {
        const double mid_s = std::chrono::duration<double>(mid1.first - mid0.first).count();
        const double mid = double(mid1.second - mid0.second) / (double(baud) / 10.0 * mid_s);
        std::printf("  firmware link busy %.1f%% in the middle of the print (lines %zu to %zu, %.2f s): %s\n", 100.0 * mid, total / 10,
                    total * 9 / 10, mid_s, mid >= 0.98 ? "target >= 98% met" : "below the 98% target");
    }
    if (baud > 0) {
        print_gaps("start (to a tenth of the lines)", phases[0]);
        print_gaps("middle", phases[1]);
        print_sizes(phases[1]);
        print_gaps("end (from nine tenths)", phases[2]);
        std::printf("  link idle after the last byte until xlate5 was idle: %.4f s\n", tail);
    }
    if (baud > 0)
        std::printf("  firmware link busy %.1f%% of the whole run (%llu bytes of %.0f it could carry), %s\n", 100.0 * double(bytes) / wire_capacity,
                    static_cast<unsigned long long>(bytes), wire_capacity,
                    "start and end included");
    std::printf("  sender send->ok latency: p50 %.0f us, p99 %.0f us; with room in the queue (%llu lines, the first apart): p50 %.0f us, p99 %.0f us\n",
                sender.latency.percentile(0.5), sender.latency.percentile(0.99), static_cast<unsigned long long>(sender.with_room.count),
                sender.with_room.percentile(0.5), sender.with_room.percentile(0.99));
    {
        // Whatever xlate5 adds to a line's round trip lies inside that round trip, so the round
        // trips' p99 bounds from above the p99 of what xlate5 adds.
        const double bound = sender.with_room.percentile(0.99);
        std::printf("  xlate5 adds at most %.0f us p99 to a round trip with room in the queue (the whole round trip's p99; target < 1000 us: %s)\n",
                    bound, bound < 1000 ? "met" : "not shown");
    }
    {
        const auto& f = parts.service->firmware()->stats();
        std::printf("  firmware link: %llu lines sent, %llu resends, %llu timeouts, %llu probes, %llu busy\n",
                    static_cast<unsigned long long>(f.sent), static_cast<unsigned long long>(f.resend_requests),
                    static_cast<unsigned long long>(f.timeouts), static_cast<unsigned long long>(f.probes), static_cast<unsigned long long>(f.busy));
    }
    std::printf("  host: load average %s before, %s after; CPU steal %.1f%% during the run\n", load_before.c_str(), Host::load().c_str(), steal);
    rusage ru{};
    ::getrusage(RUSAGE_SELF, &ru);
    const double cpu = double(ru.ru_utime.tv_sec + ru.ru_stime.tv_sec) + 1e-6 * double(ru.ru_utime.tv_usec + ru.ru_stime.tv_usec);
    std::printf("  peak RSS %.1f MB, CPU %.2f s (%.0f%% of one core; the whole process: sender, xlate5, virtual printer on one thread)\n",
                double(ru.ru_maxrss) / 1024.0, cpu, 100.0 * cpu / seconds);

    // The same sender straight to a virtual printer (no xlate5), for the latency xlate5 adds.
    if (baud == 0) {
        Pty pty;
        const std::string path = pty.path();
        const int sender_fd = ::open(path.c_str(), O_RDWR | O_NOCTTY | O_CLOEXEC);
        SimOptions so;
        so.axes = "XYZAB";
        auto sim = std::make_shared<VirtualPrinter>(io, pty.release_master(), so);
        sim->start();
        std::vector<std::string> lines;
        for (std::size_t i = 0; i < total; ++i) lines.push_back(print_line(i));
        const auto commands = firmware_commands(machine, lines);
        Sender direct(io, sender_fd, commands.size(), [&](std::size_t i) { return commands[i]; });
        direct.send();
        run(io, [&] { return direct.done; }, 3600);
        const double p50 = direct.latency.percentile(0.5), p99 = direct.latency.percentile(0.99);
        std::printf("direct to the virtual printer (the translated lines): p50 %.0f us, p99 %.0f us\n", p50, p99);
        // For context only: figures of two separate runs do not subtract into what xlate5 adds
        // to a line (a hiccup in either run moves its p99 alone, and here even the medians'
        // difference has come out negative), so no difference is printed; the bound above is
        // the figure for the target.
    }
    std::string cmd = std::string("rm -rf ") + dir;
    return std::system(cmd.c_str()) == 0 && ok ? 0 : 1;
}
