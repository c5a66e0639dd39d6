// Benchmark (not a test): the whole chain, sender -> xlate5 serve -> virtual printer, on real
// pseudo-terminals in one process. Reports lines/s, how busy the firmware's link is kept when
// it is the bottleneck (does xlate5 ever starve it?), and the latency xlate5 adds per line:
// the sender's send-to-ok time through xlate5 against the same sender talking to the virtual
// printer directly.
//   bench_service [lines=20000] [baud=0 (unlimited) | 115200 | 250000 ...] [machine=rw2]
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fcntl.h>
#include <random>
#include <spdlog/spdlog.h>
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

// Ping-pong sender, numbered and checksummed (as printcore and OctoPrint send while printing).
struct Sender {
    std::shared_ptr<DescriptorLink> link;
    std::vector<std::string> lines;
    std::size_t next = 0;
    std::int64_t resend = -1;
    Clock::time_point sent_at;
    std::vector<double> latency_us;
    bool done = false;

    Sender(asio::io_context& io, int fd, std::vector<std::string> l) : lines(std::move(l)) {
        make_raw(fd);
        link = std::make_shared<DescriptorLink>(asio::posix::stream_descriptor(io, fd), "bench sender");
        link->start([this](std::string_view r) { on_line(r); }, [](const std::string&) {});
    }
    void send() {
        if (next >= lines.size()) {
            done = true;
            return;
        }
        sent_at = Clock::now();
        link->send(proto::numbered(std::int64_t(next) + 1, lines[next]) + "\n");
    }
    void on_line(std::string_view r) {
        const auto c = proto::classify(r);
        if (c.kind == proto::ReplyKind::Resend) resend = c.resend_line;
        if (c.kind != proto::ReplyKind::Ok) return;
        latency_us.push_back(std::chrono::duration<double, std::micro>(Clock::now() - sent_at).count());
        if (resend > 0) next = std::size_t(resend - 1), resend = -1;
        else ++next;
        send();
    }
};

std::vector<std::string> print_lines(std::size_t n) {
    std::vector<std::string> l = {"G28", "G92 A-168", "G1 A0 B0 F3000", "M83"};
    std::mt19937_64 rng(3);
    std::uniform_real_distribution<double> step(-0.8, 0.8), turn(-1.5, 1.5);
    double x = 100, y = 100, a = 0, b = 0;
    char buf[160];
    for (std::size_t i = 0; i < n; ++i) {
        x = std::clamp(x + step(rng), 60.0, 140.0), y = std::clamp(y + step(rng), 60.0, 140.0);
        a = std::clamp(a + turn(rng), -90.0, 90.0), b = std::clamp(b + turn(rng), -30.0, 30.0);
        std::snprintf(buf, sizeof buf, "G1 X%.3f Y%.3f Z10 A%.2f B%.2f E0.02 F1800", x, y, a, b);
        l.emplace_back(buf);
    }
    return l;
}

double percentile(std::vector<double> v, double p) {
    if (v.empty()) return 0;
    std::sort(v.begin(), v.end());
    return v[std::min(v.size() - 1, std::size_t(p * double(v.size())))];
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
    spdlog::set_level(spdlog::level::warn);
    std::setvbuf(stdout, nullptr, _IOLBF, 0);
    const auto lines = print_lines(n);

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
    const Machine machine = load_machine(machine_name);
    Assembly parts;
    assemble(io, cfg, machine, parts);
    run(io, [&] { return parts.service->firmware()->state() == FirmwareLink::State::Ready; }, 5);
    Sender sender(io, ::open(cfg.pty.c_str(), O_RDWR | O_NOCTTY | O_CLOEXEC), lines);
    const auto t0 = Clock::now();
    sender.send();
    const bool ok = run(io, [&] { return sender.done && parts.service->idle(); }, 3600);
    const double seconds = std::chrono::duration<double>(Clock::now() - t0).count();
    const auto executed = parts.sim->stats().executed;
    const auto bytes = parts.sim->stats().bytes;
    const double wire_capacity = baud > 0 ? double(baud) / 10.0 * seconds : 0;  // bytes the link could carry
    std::printf("through xlate5 (%s, %s):\n", machine_name.c_str(), baud > 0 ? (std::to_string(baud) + " baud").c_str() : "unlimited link");
    std::printf("  %zu sender lines in %.2f s: %.0f lines/s in, %.0f lines/s to the firmware (%llu executed)%s\n", lines.size(),
                seconds, double(lines.size()) / seconds, double(executed) / seconds, static_cast<unsigned long long>(executed),
                ok ? "" : "  (DID NOT FINISH)");
    if (baud > 0)
        std::printf("  firmware link busy %.1f%% of the time (%llu bytes of %.0f it could carry): %s\n", 100.0 * double(bytes) / wire_capacity,
                    static_cast<unsigned long long>(bytes), wire_capacity,
                    double(bytes) / wire_capacity > 0.97 ? "xlate5 never starves it" : "the link waits on xlate5");
    std::printf("  sender send->ok latency: p50 %.0f us, p99 %.0f us\n", percentile(sender.latency_us, 0.5), percentile(sender.latency_us, 0.99));

    // The same sender straight to a virtual printer (no xlate5), for the latency xlate5 adds.
    if (baud == 0) {
        Pty pty;
        const std::string path = pty.path();
        const int sender_fd = ::open(path.c_str(), O_RDWR | O_NOCTTY | O_CLOEXEC);
        SimOptions so;
        so.axes = "XYZAB";
        auto sim = std::make_shared<VirtualPrinter>(io, pty.release_master(), so);
        sim->start();
        Sender direct(io, sender_fd, firmware_commands(machine, lines));
        direct.send();
        run(io, [&] { return direct.done; }, 3600);
        const double p50 = percentile(direct.latency_us, 0.5), p99 = percentile(direct.latency_us, 0.99);
        std::printf("direct to the virtual printer (the translated lines): p50 %.0f us, p99 %.0f us\n", p50, p99);
        std::printf("latency xlate5 adds per line: p50 %.0f us, p99 %.0f us\n", percentile(sender.latency_us, 0.5) - p50,
                    percentile(sender.latency_us, 0.99) - p99);
    }
    std::string cmd = std::string("rm -rf ") + dir;
    return std::system(cmd.c_str()) == 0 && ok ? 0 : 1;
}
