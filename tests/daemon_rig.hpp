// SPDX-License-Identifier: GPL-3.0-or-later
// The service under test, wired as `xlate5 serve` wires it (real pseudo-terminals, real Asio
// I/O, the virtual printer on the far end), plus a sender that talks to it the way Printrun's
// printcore and cncjs do, and the offline translation to compare the executed commands with.
#pragma once
#include <doctest/doctest.h>

#include <algorithm>
#include <chrono>
#include <fcntl.h>
#include <filesystem>
#include <functional>
#include <random>
#include <spdlog/spdlog.h>
#include <string>
#include <unistd.h>
#include <vector>

#include "daemon/line_protocol.hpp"
#include "tests/helpers.hpp"
#include "daemon/link.hpp"
#include "daemon/ports.hpp"
#include "daemon/serve.hpp"
#include "translators/kinematics/kinematics.hpp"
#include "translators/machine/machine.hpp"
#include "translators/pipeline/translator.hpp"

namespace xlate5::test {


// A sender: ping-pong (one line in flight), numbered and checksummed like printcore/OctoPrint,
// or bare like cncjs. On "Resend: n" it goes back to line n, as printcore does.
class TestSender {
public:
    TestSender(asio::io_context& io, const std::string& path, bool numbered = true) : numbered_(numbered) {
        const int fd = ::open(path.c_str(), O_RDWR | O_NOCTTY | O_CLOEXEC);
        REQUIRE_MESSAGE(fd >= 0, "cannot open " << path);
        make_raw(fd);
        link_ = std::make_shared<DescriptorLink>(asio::posix::stream_descriptor(io, fd), "test sender");
        link_->start([this](std::string_view l) { on_line(l); }, [this](const std::string& why) { closed = why.empty() ? "closed" : why; });
    }
    ~TestSender() { link_->close(); }

    // Sends every line, each after the previous one's ok; `done` when the last is acknowledged.
    void stream(std::vector<std::string> lines) {
        lines_ = std::move(lines);
        index_ = 0;
        if (numbered_) {
            hello_ = true;
            write(0, "M110 N0");
        } else {
            next();
        }
    }
    bool done() const { return !lines_.empty() && index_ >= lines_.size() && !waiting_; }
    // Sends one line now, outside the stream (e.g. M112 while the stream is held).
    void send_now(const std::string& command) { link_->send(command + "\n"); }
    void send_raw(const std::string& line) { link_->send(line + "\n"); }

    std::vector<std::string> received;  // everything but ok and Resend
    std::vector<std::string> oks;
    std::size_t resends = 0;
    std::string closed;
    std::chrono::steady_clock::time_point last_ok = std::chrono::steady_clock::now();
    double longest_wait = 0;  // seconds, the longest it waited for an ok

private:
    void write(std::int64_t n, const std::string& cmd) {
        sent_at_ = std::chrono::steady_clock::now();
        waiting_ = true;
        link_->send((numbered_ ? proto::numbered(n, cmd) : cmd) + "\n");
    }
    void next() {
        if (index_ >= lines_.size()) return;
        write(std::int64_t(index_) + 1, lines_[index_]);
    }
    void on_line(std::string_view l) {
        const auto r = proto::classify(l);
        if (r.kind == proto::ReplyKind::Resend) {
            ++resends;
            resend_to_ = r.resend_line;
            return;
        }
        if (r.kind != proto::ReplyKind::Ok) {
            received.emplace_back(l);
            return;
        }
        oks.emplace_back(l);
        const auto now = std::chrono::steady_clock::now();
        longest_wait = std::max(longest_wait, std::chrono::duration<double>(now - sent_at_).count());
        waiting_ = false;
        if (hello_) {
            hello_ = false;
            next();
            return;
        }
        if (resend_to_ > 0) {
            index_ = std::size_t(resend_to_ - 1);
            resend_to_ = -1;
        } else {
            ++index_;
        }
        next();
    }

    std::shared_ptr<DescriptorLink> link_;
    bool numbered_;
    bool hello_ = false;
    bool waiting_ = false;
    std::vector<std::string> lines_;
    std::size_t index_ = 0;
    std::int64_t resend_to_ = -1;
    std::chrono::steady_clock::time_point sent_at_;
};

struct Rig {
    asio::io_context io;
    TempDir dir;
    ServeConfig config;
    Machine machine;
    Assembly parts;

    // `with_bodies`: the machine with its test bodies (tests/bodies/NAME.toml), so the
    // collision check runs in the service.
    explicit Rig(const std::string& machine_name, const std::function<void(ServeConfig&)>& tweak = {}, bool with_bodies = false) {
        // XLATE5_TEST_LOG=debug shows the service's log while a test runs.
        const char* level = std::getenv("XLATE5_TEST_LOG");
        spdlog::set_level(level ? spdlog::level::from_str(level) : spdlog::level::off);
        config.machine = machine_name;
        config.port = "sim";
        config.pty = (dir.path / "printer").string();
        config.firmware.boot_wait = 0.1;
        config.firmware.reply_timeout = 0.5;
        config.firmware.settle = 0.02;  // a pseudo-terminal answers within milliseconds
        config.hold_seconds = 0.2;      // the test senders stream without pauses
        config.sim.keep_executed = true;
        if (tweak) tweak(config);
        machine = with_bodies ? load_with_bodies(config.machine)
                              : load_machine(std::string(XLATE5_MACHINE_DIR_FOR_TESTS) + "/" + config.machine + ".toml");
        assemble(io, config, machine, parts);
    }
    Service& service() { return *parts.service; }
    VirtualPrinter& sim() { return *parts.sim; }

    // Runs the service until `done` holds or `seconds` pass.
    bool run_until(const std::function<bool()>& done, double seconds) {
        const auto end = std::chrono::steady_clock::now() + std::chrono::milliseconds(std::int64_t(seconds * 1000));
        while (!done()) {
            if (std::chrono::steady_clock::now() > end) return false;
            io.run_for(std::chrono::milliseconds(5));
        }
        return true;
    }
    bool ready() {
        return run_until([&] { return service().firmware()->state() == FirmwareLink::State::Ready; }, 5);
    }
    // What the virtual printer executed after its greeting (M110, M115, and the service's M114
    // that asks where the machine is), without the M105 probes xlate5 sends to resynchronise
    // (they report temperatures and move nothing).
    std::vector<std::string> executed_after_hello() const {
        const auto& e = parts.sim->executed();
        std::vector<std::string> out;
        std::size_t i = 0;
        while (i < e.size() && (e[i].rfind("M110 ", 0) == 0 || e[i] == "M115" || e[i] == "M114")) ++i;
        for (; i < e.size(); ++i)
            if (e[i] != "M105") out.push_back(e[i]);
        return out;
    }
};

// The offline translation of `lines`, as the firmware should receive it (comments stripped).
inline std::vector<std::string> offline(const Machine& m, const std::vector<std::string>& lines) { return firmware_commands(m, lines); }

// A 5-axis print for rw2: start code, then short printing moves that turn both rotaries.
inline std::vector<std::string> rw2_print(std::size_t moves, std::uint64_t seed = 7) {
    std::vector<std::string> l = {"G28", "G92 A-168", "G1 A0 B0 F3000", "M83", "G1 X100 Y100 Z10 A0 B0 F1200"};
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> step(-0.8, 0.8), turn(-1.5, 1.5);
    double x = 100, y = 100, z = 10, a = 0, b = 0;
    char buf[160];
    for (std::size_t i = 0; i < moves; ++i) {
        x = std::clamp(x + step(rng), 60.0, 140.0);
        y = std::clamp(y + step(rng), 60.0, 140.0);
        z = std::clamp(z + 0.01, 5.0, 60.0);
        a = std::clamp(a + turn(rng), -90.0, 90.0);
        b = std::clamp(b + turn(rng), -30.0, 30.0);
        if (i % 500 == 250) {
            l.push_back("M106 S" + std::to_string(i % 255));  // pass-through lines keep their place
            continue;
        }
        std::snprintf(buf, sizeof buf, "G1 X%.3f Y%.3f Z%.3f A%.2f B%.2f E%.4f", x, y, z, a, b, 0.02 + 0.001 * double(i % 7));
        l.emplace_back(buf);
    }
    return l;
}

// Streams `lines` and checks the executed sequence against the offline translation; returns
// what the sender received besides ok and Resend.
inline std::vector<std::string> stream_and_compare(Rig& rig, const std::vector<std::string>& lines, double seconds, bool numbered = true) {
    REQUIRE(rig.ready());
    const auto expected = offline(rig.machine, lines);
    TestSender sender(rig.io, rig.config.pty, numbered);
    sender.stream(lines);
    const bool finished = rig.run_until([&] { return sender.done() && rig.service().idle(); }, seconds);
    CHECK_MESSAGE(finished, "stream did not finish: executed " << rig.sim().executed().size() << " of " << expected.size());
    const auto executed = rig.executed_after_hello();
    CHECK(executed.size() == expected.size());
    // The first difference, if any, is the useful message.
    const auto mismatch = std::mismatch(executed.begin(), executed.end(), expected.begin(), expected.end());
    if (mismatch.first != executed.end() || mismatch.second != expected.end()) {
        const auto at = mismatch.first - executed.begin();
        FAIL("executed differs from the offline translation at command " << at << ": '"
             << (mismatch.first != executed.end() ? *mismatch.first : "<end>") << "' vs '"
             << (mismatch.second != expected.end() ? *mismatch.second : "<end>") << "'");
    }
    CHECK(rig.service().stop_reason().empty());
    for (const auto& r : sender.received) CHECK_MESSAGE(r.rfind("Error", 0) != 0, "sender got: " << r);
    return sender.received;
}


}  // namespace xlate5::test
