// SPDX-License-Identifier: GPL-3.0-or-later
// `xlate5 serve` as a user and systemd see it: its flags and its configuration file checked by
// one table of bounds, `serve --check`, a port that appears late, the start and end log, and
// systemd's notifications.
#include <doctest/doctest.h>

#include "helpers.hpp"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <string>
#include <thread>
#include <vector>

#include "daemon/config.hpp"
#include "daemon/log_policy.hpp"
#include "daemon/status_http.hpp"
#include "daemon/ports.hpp"
#include "daemon/virtual_printer.hpp"
#include "translators/error.hpp"

namespace fs = std::filesystem;
using namespace xlate5;
using namespace xlate5::test;

namespace {

using Result = RunResult;

Result run(const TempDir& dir, const std::string& args) { return run_xlate5(dir, args); }

std::string long_name(const ServeSetting& s) {
    const std::string n = s.names;
    return n.substr(n.rfind(',') == std::string::npos ? 0 : n.rfind(',') + 1);
}

std::size_t count_of(const std::string& hay, const std::string& needle) {
    std::size_t n = 0;
    for (auto at = hay.find(needle); at != std::string::npos; at = hay.find(needle, at + 1)) ++n;
    return n;
}

std::string joined(const std::vector<std::string>& lines) {
    std::string s;
    for (const auto& l : lines) s += l + "\n";
    return s;
}

}  // namespace

TEST_CASE("serve: flags are checked by the configuration's own bounds (no flag reaches a cast unchecked)") {
    TempDir d;
    const auto file = d.write("p.gcode", "G28\n");
    struct Case {
        std::string args, want;
    };
    // The reproducers: values that reached a float-to-int cast, a port that wrapped to 34463,
    // a port that was not a number.
    for (const Case& c : std::vector<Case>{
             {"--reply-timeout 1e300", "from 0.05 to 600 (s)"},
             {"--boot-wait 1e300", "from 0 to 60 (s)"},
             {"--drain-timeout 1e300", "from 0 to 86400 (s)"},
             {"--sim-fault reset_after=1e30", "2^53"},
             {"--sim-fault reset_after=1e999", "is not a number"},
             {"--sim-fault reset_every=2.5", "2^53"},
             {"--sim-fault reset_every=-1", "must not be negative"},
             {"--sim-fault command_ms=10001", "at most 10000 ms"},
             {"--sim-fault command_ms=-0.5", "must not be negative"},
             {"--sim-fault move_ms=3601", "at most 3600 ms"},
             {"--nudge 61", "from 0 to 60 (s)"},
             {"--tcp 127.0.0.1:99999", "'99999' in '127.0.0.1:99999' is not a port number from 0 to 65535"},
             {"--tcp 127.0.0.1:abc", "'abc' in '127.0.0.1:abc' is not a port number"},
             {"--tcp 127.0.0.1:-1", "is not a port number"},
             {"--tcp 8250", "expected HOST:PORT"},
             {"--settle 0", "from 0.001 to 60 (s)"},
             {"--max-greetings 0", "from 1 to 100"},
             {"--max-resyncs 1e9", "from 1 to 100000"},
             {"--hold-seconds 1e300", "from 0.01 to 60 (s)"},
             {"--max-pending 1", "from 2 to 1048576 (lines)"},
             {"--sim-rx-size 8", "from 16 to 1048576 (bytes)"},
             {"--rx-bytes 1.5", "from 64 to 1048576 (bytes)"},
             {"--queue-lines nan", "from 1 to 1048576 (lines)"},
             {"--log-level loud", "loud"},
         }) {
        CAPTURE(c.args);
        const Result r = run(d, "serve --printer sim --no-pty --tcp 127.0.0.1:0 " + c.args + " --check " + quote(file.string()));
        CHECK(r.code == 2);
        CHECK(r.err.rfind("xlate5: ", 0) == 0);
        CHECK(contains(r.err, c.want));
        CHECK_FALSE(contains(r.err, "stoi"));
        CHECK(r.out.empty());
    }
    // The same port in the configuration file, and a server that would have bound it.
    const auto cfg = d.write("bad.toml", "[firmware]\nport = \"sim\"\n[sender]\ntcp = \"127.0.0.1:99999\"\n");
    CHECK_THROWS_WITH_AS(load_serve_config(cfg.string()), doctest::Contains("bad.toml:4: sender.tcp: '99999'"), MachineError);
    const Result served = run(d, "serve --printer sim --no-pty --tcp 127.0.0.1:99999");
    CHECK(served.code == 2);
    CHECK_FALSE(contains(served.err, "34463"));
}

TEST_CASE("serve: every configuration key has a flag, and file and flag refuse the same values with the same words") {
    TempDir d;
    const Result help = run(d, "serve --help");
    REQUIRE(help.code == 0);
    const auto file = d.write("p.gcode", "G28\n");
    int numeric = 0;
    for (const auto& row : serve_settings()) {
        CAPTURE(row.key);
        CHECK(contains(help.out, long_name(row)));
        CHECK(contains(help.out, std::string("[") + row.key + "]"));
        if (row.kind != ServeSetting::Kind::Number && row.kind != ServeSetting::Kind::Whole) continue;
        ++numeric;
        const bool whole = row.kind == ServeSetting::Kind::Whole;
        const std::string key = row.key, section = key.find('.') == std::string::npos ? "" : key.substr(0, key.find('.'));
        const std::string name = key.substr(key.find('.') == std::string::npos ? 0 : key.find('.') + 1);
        const auto toml = [&](const std::string& value) {
            return d.write("t.toml", (section.empty() ? "" : "[" + section + "]\n") + name + " = " + value + "\n").string();
        };
        const auto text = [whole](double v) {
            char buf[64];
            std::snprintf(buf, sizeof buf, whole ? "%.0f" : "%.15g", v);
            return std::string(buf);
        };
        const std::string range = serve_setting_range(row);
        for (const double bad : {row.hi + (whole ? 1.0 : std::max(1.0, row.hi)), row.lo - 1}) {
            if (bad < 0 && row.lo == 0 && whole) continue;  // written as "-1": refused the same, checked once above
            CAPTURE(bad);
            CHECK_THROWS_WITH_AS(load_serve_config(toml(text(bad))), doctest::Contains((key + ": '" + text(bad) + "' is not").c_str()), MachineError);
            CHECK_THROWS_WITH_AS(load_serve_config(toml(text(bad))), doctest::Contains(range.c_str()), MachineError);
            const Result r = run(d, "serve --printer sim " + long_name(row) + " " + text(bad) + " --check " + quote(file.string()));
            CHECK(r.code == 2);
            CHECK(contains(r.err, long_name(row)));
            CHECK(contains(r.err, range));
        }
        // The bounds themselves are taken, by both.
        for (const double good : {row.lo, row.hi}) {
            ServeConfig c = load_serve_config(toml(text(good)));
            CHECK(serve_setting_text(c, row) == text(good));
            ServeConfig f;
            apply_serve_setting(f, row, text(good));
            CHECK(serve_setting_text(f, row) == text(good));
        }
    }
    CHECK(numeric >= 20);
    // Flags override the file; --check shows what the link will use.
    const auto cfg = d.write("c.toml", "[firmware]\nport = \"/dev/ttyUSB7\"\nrx_bytes = 255\nwindow = 3\n");
    const Result over = run(d, "serve -m rw2 --config " + quote(cfg.string()) + " --window 4 --max-line 120 --check " + quote(file.string()));
    CHECK(over.code == 0);
    CHECK(contains(over.out, "/dev/ttyUSB7, marlin, 115200 baud; 4 lines in flight, at most 255 bytes in flight"));
    CHECK(contains(over.out, "lines up to 120 bytes"));
}

TEST_CASE("serve: a port must be given; the shipped configuration gives none") {
    TempDir d;
    const auto dir = fs::path(XLATE5_MACHINE_DIR_FOR_TESTS).parent_path();
    const std::string pty = (d.path / "printer").string();
    const Result r = run(d, "serve --config " + quote((dir / "config" / "xlate5.toml").string()) + " --pty " + quote(pty));
    CHECK(r.code == 2);
    CHECK(contains(r.err, "--port DEVICE"));
    CHECK(contains(r.err, "[firmware] port"));
    CHECK_FALSE(fs::exists(fs::symlink_status(pty)));
}

TEST_CASE("serve: the machine must be given, by --machine or the configuration's machine; none is assumed") {
    TempDir d;
    const auto file = d.write("p.gcode", "G28\nG1 X10 Y10 Z10 F600\n");
    const std::string pty = (d.path / "printer").string();
    // Without one: refused before anything starts (no pseudo-terminal), --check included.
    for (const std::string& args : std::vector<std::string>{"serve --printer sim --pty " + quote(pty),
                                                            "serve --printer sim --no-pty --tcp 127.0.0.1:0",
                                                            "serve --printer sim --check " + quote(file.string())}) {
        CAPTURE(args);
        const Result r = run(d, args);
        CHECK(r.code == 2);
        CHECK(r.err.rfind("xlate5: ", 0) == 0);
        CHECK(contains(r.err, "needs the machine: --machine NAME|PATH"));
        CHECK(contains(r.err, "in --config FILE"));
        CHECK(r.out.empty());
        CHECK_FALSE(fs::exists(fs::symlink_status(pty)));
    }
    // The shipped configuration names none either (it says the key is required).
    const auto shipped = fs::path(XLATE5_MACHINE_DIR_FOR_TESTS).parent_path() / "config" / "xlate5.toml";
    CHECK(load_serve_config(shipped.string()).machine.empty());
    const Result from_shipped = run(d, "serve --config " + quote(shipped.string()) + " --printer sim --check " + quote(file.string()));
    CHECK(from_shipped.code == 2);
    CHECK(contains(from_shipped.err, "needs the machine"));
    // Given either way, it is the one used.
    const auto cfg = d.write("m.toml", "machine = \"pentarod\"\n[firmware]\nport = \"sim\"\n");
    const Result by_file = run(d, "serve --config " + quote(cfg.string()) + " --check " + quote(file.string()));
    CHECK(by_file.code == 0);
    CHECK(contains(by_file.out, "(machine pentarod)"));
    const Result by_flag = run(d, "serve --config " + quote(cfg.string()) + " -m rw2 --check " + quote(file.string()));
    CHECK(by_flag.code == 0);
    CHECK(contains(by_flag.out, "(machine rw2)"));
    const Result top = run(d, "--machine wpi5 serve --printer sim --check " + quote(file.string()));
    CHECK(top.code == 0);
    CHECK(contains(top.out, "(machine wpi5)"));
}

TEST_CASE("serve --check: where serve releases held output, and where it would cancel what offline keeps") {
    TempDir d;
    const auto dir = fs::path(XLATE5_MACHINE_DIR_FOR_TESTS).parent_path();
    // A real example: serve prints it as offline.
    const Result example = run(d, "serve --printer sim -m rw2 --check " + quote((dir / "examples" / "rw2_flared_wall.gcode").string()));
    CHECK(example.code == 0);
    CHECK(contains(example.out, "serve prints the same joint moves as offline translation"));
    CHECK(contains(example.out, "the built-in virtual printer"));
    // The unwinding layer change prints the same; an M400 right after its travel move makes the
    // unwind impossible for serve (the held travel move has gone to the firmware) while offline
    // translation keeps the file.
    const auto plain = d.write("plain.gcode", joined(unwinding_print(false)));
    const Result same = run(d, "serve --printer sim -m rw2 --check " + quote(plain.string()));
    CHECK(same.code == 0);
    CHECK(contains(same.out, "serve prints the same joint moves as offline translation"));
    const auto waits = unwinding_print(true);
    const auto waiting = d.write("wait.gcode", joined(waits));
    const Result offline = run(d, "-m rw2 -i " + quote(waiting.string()));
    REQUIRE(offline.code == 0);
    const Result cancel = run(d, "serve --printer sim -m rw2 --check " + quote(waiting.string()));
    CHECK(cancel.code == 1);
    std::size_t m400 = 0;
    while (waits[m400] != "M400") ++m400;
    CHECK(contains(cancel.out, "held output released before a wait or report (offline keeps holding it): 1\n  line " + std::to_string(m400 + 1) +
                                   " 'M400'"));
    CHECK(contains(cancel.out, "serve would cancel the print at line "));
    CHECK(contains(cancel.out, "offline translation keeps it"));
    CHECK_FALSE(contains(cancel.out, "serve prints the same"));
    // A line too long for the firmware's line buffer is split (F on a line of its own).
    const auto longline = d.write("long.gcode", "G28\nG1 X100.123456789 Y100.123456789 Z10.123456789 A0.123456789 B0.123456789 F1234.56789\n");
    const Result split = run(d, "serve --printer sim -m rw2 --max-line 60 --check " + quote(longline.string()));
    CHECK(split.code == 0);
    CHECK(contains(split.out, "split or shortened for the firmware's line buffer: 1\n  line 2 "));
    // Too short for any split: serve would cancel, and says why.
    const Result too_short = run(d, "serve --printer sim -m rw2 --max-line 40 --check " + quote(longline.string()));
    CHECK(too_short.code == 1);
    CHECK(contains(too_short.out, "is longer than the firmware's line buffer"));
    CHECK(contains(too_short.out, "raise max_line"));
}

TEST_CASE("serve: a firmware port that appears late is waited for, said once; start and end logged; systemd notified") {
    TempDir d;
    const std::string late = (d.path / "late").string(), printer = (d.path / "printer").string(), notify = (d.path / "notify").string();
    // systemd's side of the notification socket.
    const int ns = ::socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    REQUIRE(ns >= 0);
    sockaddr_un addr{};
    addr.sun_family = AF_UNIX;
    std::snprintf(addr.sun_path, sizeof addr.sun_path, "%s", notify.c_str());
    REQUIRE(::bind(ns, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0);
    std::vector<std::string> notes;
    const auto collect = [&](int ms) {
        pollfd p{ns, POLLIN, 0};
        char buf[4096];
        while (::poll(&p, 1, ms) > 0) {
            const auto n = ::recv(ns, buf, sizeof buf, 0);
            if (n > 0) notes.emplace_back(buf, std::size_t(n));
            ms = 0;
        }
    };
    const auto noted = [&](const std::string& what) {
        for (const auto& n : notes)
            if (contains(n, what)) return true;
        return false;
    };
    const std::string log = (d.path / "serve.log").string();
    const pid_t pid = ::fork();
    REQUIRE(pid >= 0);
    if (pid == 0) {
        const int fd = ::open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
        ::dup2(fd, 2);
        ::setenv("NOTIFY_SOCKET", notify.c_str(), 1);
        ::unsetenv("JOURNAL_STREAM");
        ::execl(XLATE5_BINARY, "xlate5", "serve", "-m", "rw2", "--port", late.c_str(), "--pty", printer.c_str(), "--boot-wait", "0.2",
                static_cast<char*>(nullptr));
        ::_exit(127);
    }
    // The printer is off: the service waits (no exit, no sender endpoint yet) and says so once.
    std::this_thread::sleep_for(std::chrono::milliseconds(1200));
    collect(100);
    int status = 0;
    CHECK(::waitpid(pid, &status, WNOHANG) == 0);
    CHECK_FALSE(fs::exists(fs::symlink_status(printer)));
    CHECK(noted("READY=1"));
    CHECK(noted("STATUS=waiting for " + late));
    // Switched on: a Marlin-like virtual printer behind a pseudo-terminal at that path.
    asio::io_context io;
    Pty port(late);
    const int hold = ::open(port.path().c_str(), O_RDWR | O_NOCTTY | O_CLOEXEC);  // keeps the master readable until xlate5 opens it
    SimOptions so;
    so.axes = "XYZAB";
    auto sim = std::make_shared<VirtualPrinter>(io, port.release_master(), so);
    sim->start();
    std::atomic<bool> quit{false};
    std::thread firmware([&] {
        while (!quit) io.run_for(std::chrono::milliseconds(20));
    });
    // The sender's end appears once the firmware answered, and the printer answers through it.
    bool up = false;
    for (int i = 0; i < 200 && !up; ++i) {
        up = fs::exists(fs::symlink_status(printer));
        if (!up) std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    CHECK(up);
    std::string got;
    if (up) {
        const int s = ::open(printer.c_str(), O_RDWR | O_NOCTTY | O_CLOEXEC);
        REQUIRE(s >= 0);
        make_raw(s);
        for (int attempt = 0; attempt < 50 && !contains(got, "ok"); ++attempt) {
            if (attempt % 10 == 0) CHECK(::write(s, "M105\n", 5) == 5);
            pollfd p{s, POLLIN, 0};
            char buf[512];
            if (::poll(&p, 1, 100) > 0) {
                const auto n = ::read(s, buf, sizeof buf);
                if (n > 0) got.append(buf, std::size_t(n));
            }
        }
        ::close(s);
    }
    CHECK(contains(got, "ok T:"));
    for (int i = 0; i < 50 && !noted("STATUS=idle; 1 lines from senders"); ++i) collect(100);
    CHECK(noted("STATUS=idle; 1 lines from senders"));
    ::kill(pid, SIGTERM);
    REQUIRE(::waitpid(pid, &status, 0) == pid);
    CHECK(WIFEXITED(status));
    CHECK(WEXITSTATUS(status) == 0);
    collect(200);
    CHECK(noted("STOPPING=1"));
    quit = true;
    firmware.join();
    ::close(hold);
    ::close(ns);
    const std::string text = read(log);
    CAPTURE(text);
    CHECK(count_of(text, "waiting for " + late) == 1);
    CHECK(contains(text, "machine rw2; firmware " + late + ", marlin, 115200 baud"));
    CHECK(contains(text, "served "));
    CHECK(contains(text, "1 lines from senders"));
    CHECK(contains(text, "0 firmware faults"));
}

TEST_CASE("serve's log: the journal only when standard error is the journal's stream (systemd's rule)") {
    TempDir d;
    const auto file = d.write("stderr.txt", "");
    const int fd = ::open(file.c_str(), O_RDONLY | O_CLOEXEC);
    REQUIRE(fd >= 0);
    struct stat st {};
    REQUIRE(::fstat(fd, &st) == 0);
    const std::string same = std::to_string(st.st_dev) + ":" + std::to_string(st.st_ino);
    CHECK(journal_stream_is(fd, same.c_str()));
    CHECK_FALSE(journal_stream_is(fd, (std::to_string(st.st_dev) + ":" + std::to_string(st.st_ino + 1)).c_str()));
    CHECK_FALSE(journal_stream_is(fd, (std::to_string(st.st_dev + 1) + ":" + std::to_string(st.st_ino)).c_str()));
    CHECK_FALSE(journal_stream_is(fd, "8:12345"));
    CHECK_FALSE(journal_stream_is(fd, (same + "x").c_str()));
    CHECK_FALSE(journal_stream_is(fd, (":" + std::to_string(st.st_ino)).c_str()));
    CHECK_FALSE(journal_stream_is(fd, ""));
    CHECK_FALSE(journal_stream_is(fd, nullptr));
    ::close(fd);
}

TEST_CASE("serve's log budget: the first messages of a window whole, the rest counted and told with the next one") {
    using namespace std::chrono_literals;
    LogBudget b(3, 60s);
    const auto t0 = LogBudget::Clock::time_point{} + 1h;
    std::uint64_t skipped = 99;
    for (int i = 0; i < 3; ++i) {
        CHECK(b.allow(t0 + std::chrono::seconds(i), skipped));
        CHECK(skipped == 0);
    }
    CHECK_FALSE(b.allow(t0 + 10s, skipped));
    CHECK_FALSE(b.allow(t0 + 59s, skipped));
    CHECK(b.allow(t0 + 60s, skipped));
    CHECK(skipped == 2);
    CHECK(b.allow(t0 + 61s, skipped));
    CHECK(skipped == 0);
}

namespace {

// `xlate5 serve` on the virtual printer with a pseudo-terminal for senders, standard error into
// `log`, JOURNAL_STREAM set to `journal` (or unset when empty).
pid_t start_serve(const std::string& log, const std::string& printer, const std::function<std::string(int)>& journal) {
    const pid_t pid = ::fork();
    if (pid == 0) {
        const int fd = ::open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
        ::dup2(fd, 2);
        const std::string j = journal(2);
        if (j.empty()) ::unsetenv("JOURNAL_STREAM");
        else ::setenv("JOURNAL_STREAM", j.c_str(), 1);
        ::unsetenv("NOTIFY_SOCKET");
        ::execl(XLATE5_BINARY, "xlate5", "serve", "-m", "rw2", "--printer", "sim", "--pty", printer.c_str(), "--boot-wait", "0.2",
                static_cast<char*>(nullptr));
        ::_exit(127);
    }
    return pid;
}

bool wait_for_path(const std::string& p) {
    for (int i = 0; i < 200; ++i) {
        if (fs::exists(fs::symlink_status(p))) return true;
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    return false;
}

int stop_serve(pid_t pid) {
    ::kill(pid, SIGTERM);
    int status = 0;
    if (::waitpid(pid, &status, 0) != pid || !WIFEXITED(status)) return -1;
    return WEXITSTATUS(status);
}

}  // namespace

TEST_CASE("serve's log: on standard error when JOURNAL_STREAM names another file; 'sender connected' when one does; each refused line") {
    TempDir d;
    const std::string log = (d.path / "serve.log").string(), printer = (d.path / "printer").string();
    // The issue's reproducer: JOURNAL_STREAM inherited from somewhere else.
    const pid_t pid = start_serve(log, printer, [](int) { return std::string("8:12345"); });
    REQUIRE(pid > 0);
    REQUIRE(wait_for_path(printer));
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    const std::string before = read(log);
    CAPTURE(before);
    CHECK(contains(before, "serve: machine rw2"));
    CHECK(contains(before, "senders: open " + printer));
    CHECK_FALSE(contains(before, "sender connected"));  // nobody has opened the printer yet
    // A sender opens it and types lines the translator refuses (no print: nothing is cancelled).
    const int s = ::open(printer.c_str(), O_RDWR | O_NOCTTY | O_CLOEXEC);
    REQUIRE(s >= 0);
    make_raw(s);
    std::string got;
    const int bad = 14;
    for (int i = 0; i < bad; ++i) {
        const std::string line = "G1 X" + std::to_string(i) + " Y..2\n";
        CHECK(::write(s, line.data(), line.size()) == ssize_t(line.size()));
    }
    for (int i = 0; i < 100 && count_of(got, "ok") < std::size_t(bad); ++i) {
        pollfd p{s, POLLIN, 0};
        char buf[4096];
        if (::poll(&p, 1, 100) > 0) {
            const auto n = ::read(s, buf, sizeof buf);
            if (n > 0) got.append(buf, std::size_t(n));
        }
    }
    CAPTURE(got);
    CHECK(count_of(got, "echo:xlate5: refused line ") == std::size_t(bad));
    ::close(s);
    std::this_thread::sleep_for(std::chrono::milliseconds(400));
    CHECK(stop_serve(pid) == 0);
    const std::string text = read(log);
    CAPTURE(text);
    CHECK(count_of(text, "sender connected: pty " + printer) == 1);
    CHECK(contains(text, "sender closed " + printer));
    // Each refused line with its text and cause, ten a minute at most: the burst is cut there.
    CHECK(contains(text, "pty " + printer + ": refused line 1 'G1 X0 Y..2': "));
    CHECK(count_of(text, ": refused line ") == 10);
    CHECK(contains(text, "14 refused"));
}

TEST_CASE("serve's log: into the journal, not standard error, when JOURNAL_STREAM is standard error's device and inode") {
    TempDir d;
    const std::string log = (d.path / "serve.log").string(), printer = (d.path / "printer").string();
    const pid_t pid = start_serve(log, printer, [](int fd) {
        struct stat st {};
        ::fstat(fd, &st);
        return std::to_string(st.st_dev) + ":" + std::to_string(st.st_ino);
    });
    REQUIRE(pid > 0);
    REQUIRE(wait_for_path(printer));
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    CHECK(stop_serve(pid) == 0);
    const std::string text = read(log);
    CAPTURE(text);
    // Nothing of the log's own text on standard error (where no journal listens, spdlog may say
    // that it could not write to it, never the message).
    CHECK_FALSE(contains(text, "serve: machine rw2"));
    CHECK_FALSE(contains(text, "senders: open"));
    CHECK_FALSE(contains(text, "served "));
}

TEST_CASE("serve --http: the status JSON escapes what a sender wrote and writes no number it cannot") {
    StatusSnapshot s;
    s.version = "0.1.0";
    s.machine = "rw2";
    s.state = "stopped";
    s.stop_reason = "print cancelled at line 3 'G1 X\"1\"'";
    // A control byte, a backslash, a byte that is not UTF-8, a whole two-byte character (é), an
    // overlong encoding of '/' and a lone continuation byte.
    s.last_error = std::string("a\x01" "b\\c\xff" "d\xc3\xa9" "e\xc0\xaf" "f\x80", 14);
    s.joint_names = {"X", "A"};
    s.joints = {1.5, -0.0};
    s.pose = std::array<double, 6>{10, 20, NAN, 0, 0, 1};
    const std::string j = status_json(s);
    CAPTURE(j);
    CHECK(contains(j, R"("stop_reason":"print cancelled at line 3 'G1 X\"1\"'")"));
    CHECK(contains(j, "\"last_error\":\"a\\u0001b\\\\c\xef\xbf\xbd" "d\xc3\xa9" "e\xef\xbf\xbd\xef\xbf\xbd" "f\xef\xbf\xbd\""));
    CHECK(contains(j, R"("position":{"joints":{"X":1.5,"A":0},"tip":[10,20,null],"axis":[0,0,1]})"));
    CHECK(contains(j, R"("line":null)"));
    CHECK(contains(j, R"("link_busy_percent":null)"));
    CHECK(contains(j, R"("authentication":"none")"));
    // Before the firmware is there: no position.
    StatusSnapshot none;
    none.joint_names = {"X"};
    CHECK(contains(status_json(none), R"("position":null)"));
}

TEST_CASE("serve --flavor klipper: a machine whose rotaries are not in the Klipper dialect is refused at start") {
    // Klipper drops A/B words of an unregistered axis and its G92 reads only X Y Z E: rw2's
    // Marlin-dialect output (G92 A-168) would zero Z there.
    TempDir d;
    const std::string pty = (d.path / "printer").string();
    const Result r = run(d, "serve -m rw2 --port sim --flavor klipper --sim-flavor klipper --pty " + quote(pty));
    CHECK(r.code != 0);
    CHECK(contains(r.err, "firmware.flavor: klipper, but machine rw2 writes its A words in another dialect"));
    CHECK(contains(r.err, "dialect = \"klipper\""));
    CHECK_FALSE(fs::exists(fs::symlink_status(pty)));
}
