// SPDX-License-Identifier: GPL-3.0-or-later
// Hostile input: every bound on what one input may cost (docs/limits.md) holds, and each
// reproducer found by fuzzing and soaking the CLI and the service is refused clearly, at its
// line and column, instead of overflowing, running cut or stopping for good.
#include <doctest/doctest.h>

#include <fcntl.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <filesystem>
#include <string>
#include <vector>

#include "daemon/line_checker.hpp"
#include "tests/daemon_rig.hpp"
#include "translators/pipeline/arcs.hpp"
#include "translators/constants.hpp"
#include "translators/error.hpp"
#include "translators/kinematics/kinematics.hpp"
#include "translators/pipeline/lookback.hpp"
#include "translators/pipeline/translator.hpp"

using namespace xlate5;
using namespace xlate5::test;

namespace {

Machine load(const std::string& name) { return load_machine(std::string(XLATE5_MACHINE_DIR_FOR_TESTS) + "/" + name + ".toml"); }

std::size_t count_lines(const std::string& s) { return std::size_t(std::count(s.begin(), s.end(), '\n')); }

// Feeds `line` as line `no` and returns the error it raised (line 0 when none).
InputError refusal(Translator& t, const std::string& line, std::uint64_t no, std::string& out) {
    try {
        t.feed(line, no, out);
    } catch (const InputError& e) {
        return e;
    }
    return InputError("", 0, 0, "");
}

}  // namespace

TEST_CASE("arcs: turns and chords are bounded; a line cannot become an unbounded output") {
    const Machine m = load("pentarod");
    const Kinematics k(m);
    Translator t(k, {});
    std::string out;
    t.feed("G1 X10 Y0 Z5 I0 J0 K1 F1200", 1, out);
    const std::string start = out;

    // A full circle of radius 10 within the tolerance: this many chords a turn (the reference for the bounds below).
    out.clear();
    REQUIRE_NOTHROW(t.feed("G2 X10 Y0 I-10 J0", 2, out));
    const std::size_t per_turn = count_lines(out);
    REQUIRE(per_turn > 10);
    REQUIRE(per_turn * 1000 > std::size_t(kMaxPiecesPerLine));  // so P1000 is past the bound

    // P999999999: an int overflow once (one chord, exit 0); refused at the P word.
    out.clear();
    auto e = refusal(t, "G2 X10 Y0 I-10 J0 P999999999", 3, out);
    CHECK(e.line() == 3);
    CHECK(e.column() == 19);
    CHECK(std::string(e.what()).find("P (turns) must be a whole number from 1 to 1000") != std::string::npos);
    CHECK(out.empty());
    // P1000 on a 24-byte line (70,000 lines once): turns within their bound, chords past theirs.
    e = refusal(t, "G2 X10 Y0 I-10 J0 P1000", 4, out);
    CHECK(e.line() == 4);
    CHECK(e.column() == 1);
    CHECK(std::string(e.what()).find("bound on pieces per input line") != std::string::npos);
    CHECK(out.empty());
    // Within the bound an arc of several turns still runs, each turn as many chords as one.
    const int turns = int(kMaxPiecesPerLine / per_turn) - 1;
    REQUIRE(turns >= 2);
    out.clear();
    REQUIRE_NOTHROW(t.feed("G2 X10 Y0 I-10 J0 P" + std::to_string(turns), 5, out));
    CHECK(count_lines(out) >= per_turn * std::size_t(turns) - std::size_t(turns));
    CHECK(count_lines(out) <= std::size_t(kMaxPiecesPerLine));

    // The chord function itself, independent of the interpreter.
    Arc a;
    a.start = {10, 0, 0};
    a.end = a.start;
    a.offset_a = -10;
    std::vector<Eigen::Vector3d> ends;
    a.turns = kMaxArcTurns + 1;
    CHECK_FALSE(arc_chords(a, 0.01, ends).empty());
    CHECK(ends.empty());
    a.turns = kMaxArcTurns;
    CHECK(arc_chords(a, 1e-6, ends).find("more than 10000") != std::string::npos);
    a.turns = 1;
    CHECK(arc_chords(a, 0.01, ends).empty());
    CHECK(ends.size() <= std::size_t(kMaxPiecesPerLine));
}

TEST_CASE("a move needing more pieces than the bound is refused at its line and column, not written out") {
    // koc5, C unbounded: 1025 turns of C in one line became 65,520 output lines.
    const Machine m = load("koc5");
    const Kinematics k(m);
    Translator t(k, {});
    std::string out;
    t.feed("G28", 1, out);
    t.feed("G43.4", 2, out);
    out.clear();
    const auto e = refusal(t, "G1 X16.75 Z3.34 B-11.1 C-369037 F1385", 3, out);
    CHECK(e.line() == 3);
    CHECK(e.column() == 1);
    CHECK(std::string(e.what()).find("more than 10000 pieces") != std::string::npos);
    CHECK(count_lines(out) == 0);
    // Ten turns are fine (and take fewer pieces than the bound).
    REQUIRE_NOTHROW(t.feed("G1 X16.75 Z3.34 B-11.1 C-3600 F1385", 4, out));
    CHECK(count_lines(out) > 10);
    CHECK(count_lines(out) <= std::size_t(kMaxPiecesPerLine));
}

TEST_CASE("a program may lower the bound on pieces per line (never raise it): moves and arcs are refused past it") {
    Machine m = load("koc5");
    m.motion.max_pieces = 50;
    {
        const Kinematics k(m);
        Translator t(k, {});
        std::string out;
        t.feed("G28", 1, out);
        t.feed("G43.4", 2, out);
        out.clear();
        // Ten turns of C at the machine's angle tolerance: thousands of pieces, past 50.
        const auto e = refusal(t, "G1 X16.75 Z3.34 B-11.1 C-3600 F1385", 3, out);
        CHECK(e.line() == 3);
        CHECK(std::string(e.what()).find("more than 50 pieces") != std::string::npos);
        CHECK(count_lines(out) == 0);
        // A short turn fits: split as before, within the lower bound.
        REQUIRE_NOTHROW(t.feed("G1 X16.75 Z3.34 B-11.1 C-5 F1385", 4, out));
        CHECK(count_lines(out) > 1);
        CHECK(count_lines(out) <= 50);
    }
    m.motion.max_pieces = 1 << 30;  // above the bound: the bound holds
    {
        const Kinematics k(m);
        Translator t(k, {});
        std::string out;
        t.feed("G28", 1, out);
        t.feed("G43.4", 2, out);
        const auto e = refusal(t, "G1 X16.75 Z3.34 B-11.1 C-369037 F1385", 3, out);
        CHECK(std::string(e.what()).find("more than 10000 pieces") != std::string::npos);
    }
    // Arcs: the chord function and the interpreter's count of output lines.
    Arc a;
    a.start = {10, 0, 0};
    a.end = a.start;
    a.offset_a = -10;
    std::vector<Eigen::Vector3d> ends;
    REQUIRE(arc_chords(a, 0.01, ends).empty());
    const std::size_t chords = ends.size();
    REQUIRE(chords > 4);
    CHECK(arc_chords(a, 0.01, ends, int(chords) - 1).find("more than " + std::to_string(chords - 1)) != std::string::npos);
    CHECK(arc_chords(a, 0.01, ends, int(chords)).empty());
    CHECK(arc_chords(a, 0.01, ends, 1 << 30).empty());
    Machine pr = load("pentarod");
    pr.motion.max_pieces = 10;
    const Kinematics kp(pr);
    Translator t(kp, {});
    std::string out;
    t.feed("G1 X10 Y0 Z5 I0 J0 K1 F1200", 1, out);
    out.clear();
    const auto e = refusal(t, "G2 X10 Y0 I-10 J0", 2, out);
    CHECK(std::string(e.what()).find("more than 10") != std::string::npos);
    CHECK(out.empty());
}

TEST_CASE("the look-back's window is bounded by bytes as well as by lines") {
    const Machine m = load("rw2");
    const Kinematics k(m);
    // Lines fed after a travel move before the first of their output is released: with short
    // lines the window holds them all (2000 lines); with 20 KB lines it closes near 1 MB.
    const auto held_for = [&](std::size_t comment_bytes) {
        Translator t(k, {});
        t.set_lookback(Translator::kDefaultLookback);
        std::string out;
        t.feed("G28", 1, out);
        t.feed("M83", 1, out);  // relative E: every line below prints (an unchanged absolute E would be a travel)
        t.feed("G1 X100 Y100 Z10 A0 B0 F1200", 2, out);
        t.finish(out);
        out.clear();
        t.feed("G0 X101 Y100 Z10", 3, out);  // travel: a checkpoint
        const std::string comment = " ;" + std::string(comment_bytes, 'c');
        for (std::uint64_t i = 0; i < 600; ++i) {
            t.feed("G1 X" + std::to_string(100 + double(i % 50) * 0.1) + " Y100 E0.01" + comment, 4 + i, out);
            if (!out.empty()) return i + 1;
        }
        return std::uint64_t(600);
    };
    CHECK(held_for(0) == 600);
    const std::uint64_t long_lines = held_for(20000);
    CHECK(long_lines <= LookBack::kMaxWindowBytes / 20000 + 2);
    CHECK(long_lines >= LookBack::kMaxWindowBytes / 20010 - 1);
}

TEST_CASE("line checker: an N without a number is refused, never run as a command") {
    using V = proto::LineChecker::Verdict;
    for (const bool strict : {false, true}) {
        proto::LineChecker c(strict);
        REQUIRE(c.check(proto::numbered(1512, "M110 N1512")).verdict == V::Take);
        // "N1513 G1 …" with a digit flipped into ';' (the rest becomes a comment).
        const auto r = c.check("N;01513 G1 X10.5 Y20 E0.3*77");
        CHECK(r.verdict == V::Refuse);
        CHECK(r.why == proto::kErrLineNumber);
        CHECK(c.check("N G28*58").verdict == V::Refuse);
        CHECK(c.check("NX1513 G1 X1").verdict == V::Refuse);
        CHECK(c.last_line() == 1512);
        CHECK(c.check(proto::numbered(1513, "G1 X10.5")).verdict == V::Take);
    }
}

TEST_CASE("a G or M code past the lexer's bound is no code (its times ten overflowed an int)") {
    // Found by fuzz_sender_line: "M287203685".
    CHECK(proto::command_code("M287203685").letter == 0);
    CHECK(proto::command_code("G-2147483648").letter == 0);
    CHECK(proto::command_code("M99999").is('M', 99999));
    CHECK(proto::command_code("G43.4 X1").is('G', 43) == false);
    CHECK(proto::command_code("G43.4 X1").code10 == 434);
}

TEST_CASE("line checker: line numbers beyond Marlin's long are refused; last_N + 1 never overflows") {
    using V = proto::LineChecker::Verdict;
    proto::LineChecker c(true);
    REQUIRE(c.check(proto::numbered(0, "M110 N0")).verdict == V::Take);
    auto r = c.check(proto::numbered(1, "M110 N9223372036854775807"));
    CHECK(r.verdict == V::Refuse);
    CHECK(c.last_line() == 0);
    r = c.check(proto::numbered(2147483648, "M110"));
    CHECK(r.verdict == V::Refuse);
    CHECK_FALSE(c.set_last_line(9223372036854775807));
    CHECK_FALSE(c.set_last_line(-9223372036854775807 - 1));
    CHECK(c.last_line() == 0);
    // The bound itself is usable: the next line after it is refused, not wrapped.
    REQUIRE(c.check(proto::numbered(1, "M110 N2147483647")).verdict == V::Take);
    CHECK(c.last_line() == proto::kMaxLineNumber);
    CHECK(c.check(proto::numbered(-2147483648, "G28")).verdict == V::Refuse);
    CHECK(c.resend_line() == "Resend: 2147483648");
}

TEST_CASE("sender side: M110 with a number past the bound is refused; the print goes on") {
    Rig rig("rw2");
    REQUIRE(rig.ready());
    TestSender sender(rig.io, rig.config.pty);
    sender.send_raw("M110 N9223372036854775807");    // unnumbered: overflowed last_N + 1
    sender.send_raw(proto::numbered(1, "G28"));
    REQUIRE(rig.run_until([&] { return sender.oks.size() >= 2; }, 5));
    REQUIRE(!sender.received.empty());
    CHECK(sender.received[0] == "Error:Line Number is not Last Line Number+1, Last Line: 0");
    rig.run_until([&] { return rig.service().idle(); }, 5);
    CHECK(rig.executed_after_hello() == std::vector<std::string>{"G28"});
}

TEST_CASE("sender side: a line longer than the line-length bound is refused whole, never run cut") {
    // 140 KB: once its first 64 KB and its last bytes were joined and run.
    const std::string big = "G1 X10 Y10 Z5" + std::string(140000, ' ') + "A30";
    {
        Rig rig("rw2");
        REQUIRE(rig.ready());
        TestSender sender(rig.io, rig.config.pty, /*numbered=*/false);
        sender.stream({"G28", big, "G1 X20 Y10 Z5"});
        REQUIRE(rig.run_until([&] { return sender.done() && rig.service().idle(); }, 10));
        bool refused = false;
        for (const auto& r : sender.received) refused = refused || (r.find("echo:xlate5: refused line 2") == 0 && r.find("longer than 65536 bytes") != std::string::npos);
        CHECK(refused);
        const auto e = rig.executed_after_hello();
        CHECK(e == offline(rig.machine, {"G28", "G1 X20 Y10 Z5"}));
    }
    {
        // Numbered (a print): the print is cancelled there, every line before it runs.
        Rig rig("rw2");
        REQUIRE(rig.ready());
        TestSender sender(rig.io, rig.config.pty);
        sender.stream({"G28", big, "G1 X20 Y10 Z5"});
        REQUIRE(rig.run_until([&] { return sender.done() && rig.service().idle(); }, 10));
        bool cancelled = false;
        for (const auto& r : sender.received) {
            CHECK_MESSAGE(r.rfind("Error", 0) != 0, "OctoPrint would send M112 on: " << r);
            cancelled = cancelled || (r.find("echo:xlate5: print cancelled at line 2") == 0 && r.find("longer than") != std::string::npos);
        }
        CHECK(cancelled);
        CHECK(rig.service().stopped());
        CHECK(rig.executed_after_hello() == std::vector<std::string>{"G28"});
    }
}

// The sanitizer runtime needs descriptors of its own (UndefinedBehaviorSanitizer's vptr check
// opens a pipe to probe memory): with none left it reports an "invalid vptr" that is not there.
// So this one runs in the optimised build only.
TEST_CASE("TCP: with the file limit reached, accepting resumes once descriptors are free again" * doctest::skip(kAddressSanitized)) {
    // In a child process: its lowered RLIMIT_NOFILE and the descriptors it fills stay its own.
    const pid_t pid = ::fork();
    REQUIRE(pid >= 0);
    if (pid == 0) {
        int code = 10;
        try {
            Rig rig("rw2", [](ServeConfig& c) { c.tcp = "127.0.0.1:0"; });
            if (!rig.ready()) ::_exit(11);
            const auto port = rig.parts.acceptor->local_endpoint().port();
            // The client connects (the kernel completes it in the listen backlog), asks M115.
            asio::ip::tcp::socket sock(rig.io);
            sock.connect({asio::ip::make_address("127.0.0.1"), port});
            auto link = std::make_shared<TcpLink>(std::move(sock), "client");
            std::vector<std::string> got;
            link->start([&](std::string_view l) { got.emplace_back(l); }, [](const std::string&) {});
            // Every descriptor taken: the service's accept fails with EMFILE.
            const int probe = ::dup(0);
            rlimit lim{rlim_t(probe + 8), rlim_t(probe + 8)};
            ::close(probe);
            if (::setrlimit(RLIMIT_NOFILE, &lim) != 0) ::_exit(12);
            std::vector<int> fill;
            for (int fd; (fd = ::dup(0)) >= 0;) fill.push_back(fd);
            if (errno != EMFILE) ::_exit(13);
            link->send("M115\n");
            rig.run_until([] { return false; }, 0.6);
            if (!got.empty()) ::_exit(14);  // it was accepted though no descriptor was free
            for (const int fd : fill) ::close(fd);
            code = rig.run_until([&] { return !got.empty() && got.back() == "ok"; }, 5) ? 0 : 15;
            link->close();
        } catch (...) {
            code = 16;
        }
        ::_exit(code);
    }
    int status = 0;
    REQUIRE(::waitpid(pid, &status, 0) == pid);
    REQUIRE(WIFEXITED(status));
    CHECK(WEXITSTATUS(status) == 0);
}

TEST_CASE("--record: a record file truncated while the printer runs gets no hole of NUL bytes") {
    TempDir dir;
    const auto path = dir.path / "record.gcode";
    const auto first = rw2_print(1500, 3), second = rw2_print(300, 4);
    std::vector<std::string> executed;
    {
        Rig rig("rw2", [&](ServeConfig& c) { c.sim.record_path = path.string(); });
        REQUIRE(rig.ready());
        TestSender sender(rig.io, rig.config.pty);
        sender.stream(first);
        REQUIRE(rig.run_until([&] { return sender.done() && rig.service().idle(); }, 60));
        REQUIRE(std::filesystem::file_size(path) > 0);  // more than a stream buffer written
        std::filesystem::resize_file(path, 0);          // a user's "> record.gcode"
        sender.stream(second);
        REQUIRE(rig.run_until([&] { return sender.done() && rig.service().idle(); }, 60));
        executed = rig.sim().executed();
    }
    const std::string text = read(path);
    CHECK(text.find('\0') == std::string::npos);
    // It holds the tail of what ran: the buffered rest of the first part (its first line may
    // start mid-line, where the buffer was cut) and all of the second, in order.
    const auto lines = lines_of(text);
    REQUIRE(lines.size() >= 2);
    REQUIRE(lines.size() <= executed.size());
    const std::vector<std::string> tail(executed.end() - std::ptrdiff_t(lines.size()) + 1, executed.end());
    CHECK(std::vector<std::string>(lines.begin() + 1, lines.end()) == tail);
    const std::string& cut = executed[executed.size() - lines.size()];
    CHECK(cut.size() >= lines[0].size());
    CHECK(cut.compare(cut.size() - lines[0].size(), lines[0].size(), lines[0]) == 0);
    CHECK(lines.size() > second.size() / 2);
}
