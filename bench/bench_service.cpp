// Benchmark (not a test): the whole chain, sender -> xlate5 serve -> virtual printer, on real
// pseudo-terminals in one process. Reports lines/s, how busy the firmware's link is kept when
// it is the bottleneck (does xlate5 ever starve it?), and the latency xlate5 adds per line:
// the sender's send-to-ok time through xlate5 against the same sender talking to the virtual
// printer directly (unlimited link). With a limited link, the send-to-ok time of the lines sent
// while xlate5's queue had room is printed too (the rest wait for the link, by design). The
// host's load average and CPU steal over the run are printed next to the figures: on a shared
// machine they explain most of the spread.
//   bench_service [lines=20000] [baud=0 (unlimited) | 115200 | 250000 ...] [machine=rw2] [rx_bytes=127]
//                 [travel_every=0 (none: the look-back holds full 2000-line windows) | N: a travel move every N lines]
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fcntl.h>
#include <fstream>
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
#include "translators/kinematics.hpp"
#include "translators/translator.hpp"

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
    sender.send();
    // The link in the middle of the print (from a tenth of the lines to nine tenths), apart from
    // its start (the look-back holds the first window until it is decided) and its end (held
    // output goes after hold_seconds of silence from the sender): both happen once per print.
    run(io, [&] { return sender.next >= total / 10; }, 3600);
    const auto mid0 = std::make_pair(Clock::now(), parts.sim->stats().bytes);
    run(io, [&] { return sender.next >= total * 9 / 10; }, 3600);
    const auto mid1 = std::make_pair(Clock::now(), parts.sim->stats().bytes);
    const bool ok = run(io, [&] { return sender.done && parts.service->idle(); }, 3600);
    const double seconds = std::chrono::duration<double>(Clock::now() - t0).count();
    const Host host1 = Host::now();
    const double steal = host1.total > host0.total ? 100.0 * double(host1.steal - host0.steal) / double(host1.total - host0.total) : 0;
    const auto executed = parts.sim->stats().executed;
    const auto bytes = parts.sim->stats().bytes;
    const double wire_capacity = baud > 0 ? double(baud) / 10.0 * seconds : 0;  // bytes the link could carry
    std::printf("through xlate5 (%s, %s, receive-buffer budget %zu bytes):\n", machine_name.c_str(),
                baud > 0 ? (std::to_string(baud) + " baud").c_str() : "unlimited link", cfg.firmware.rx_bytes);
    std::printf("  %zu sender lines in %.2f s: %.0f lines/s in, %.0f lines/s to the firmware (%llu executed)%s\n", total,
                seconds, double(total) / seconds, double(executed) / seconds, static_cast<unsigned long long>(executed),
                ok ? "" : "  (DID NOT FINISH)");
    if (baud > 0) {
        const double mid_s = std::chrono::duration<double>(mid1.first - mid0.first).count();
        const double mid = double(mid1.second - mid0.second) / (double(baud) / 10.0 * mid_s);
        std::printf("  firmware link busy %.1f%% in the middle of the print (lines %zu to %zu, %.2f s): %s\n", 100.0 * mid, total / 10,
                    total * 9 / 10, mid_s, mid >= 0.98 ? "target >= 98% met" : "below the 98% target");
    }
    if (baud > 0)
        std::printf("  firmware link busy %.1f%% of the whole run (%llu bytes of %.0f it could carry), %s\n", 100.0 * double(bytes) / wire_capacity,
                    static_cast<unsigned long long>(bytes), wire_capacity,
                    "start and end included");
    std::printf("  sender send->ok latency: p50 %.0f us, p99 %.0f us; with room in the queue (%llu lines, the first apart): p50 %.0f us, p99 %.0f us\n",
                sender.latency.percentile(0.5), sender.latency.percentile(0.99), static_cast<unsigned long long>(sender.with_room.count),
                sender.with_room.percentile(0.5), sender.with_room.percentile(0.99));
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
        std::printf("latency xlate5 adds per line against the printer alone: p50 %.0f us, p99 %.0f us (target p99 < 1000 us)\n", sender.latency.percentile(0.5) - p50,
                    sender.latency.percentile(0.99) - p99);
    }
    std::string cmd = std::string("rm -rf ") + dir;
    return std::system(cmd.c_str()) == 0 && ok ? 0 : 1;
}
