// SPDX-License-Identifier: GPL-3.0-or-later
// The command line as a user and a script see it: exit codes (0 ok, 1 bad G-code, 2 usage,
// 3 machine, 4 I/O), messages, atomic -o, --set, --inverse, machines, --version.
#include <doctest/doctest.h>

#include "helpers.hpp"
#include "translators/inspect/three_js.hpp"

#include <cctype>

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <array>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

namespace fs = std::filesystem;
using namespace xlate5::test;

namespace {





using Result = RunResult;

// Runs the xlate5 binary with `args` (already quoted), standard input from `stdin_text`, under
// `env` (an env(1) prefix, e.g. "env -u XLATE5_MACHINES ").
Result run(const TempDir& dir, const std::string& args, const std::string& stdin_text = "", const std::string& env = "") {
    return run_xlate5(dir, args, env, RunInput{stdin_text});
}

// The lines of a translation's output after its first, which must be xlate5's header naming
// the machine and the space written.
std::vector<std::string> body_lines(const std::string& out, const std::string& machine, const std::string& space = "joint space") {
    auto lines = lines_of(out);
    REQUIRE(!lines.empty());
    CHECK(lines[0].rfind("; xlate5 ", 0) == 0);
    CHECK(lines[0].find(" machine=" + machine + " " + space) != std::string::npos);
    lines.erase(lines.begin());
    return lines;
}




// Andersons (Twente 2023) eq. 4.5.
struct Xyz {
    double x, y, z;
};
Xyz eq45(double tx, double ty, double tz, double a, double b, double la, double lb = 47.9) {
    const double A = rad(a), B = rad(b);
    return {tx + std::sin(A) * la + std::cos(A) * std::sin(B) * lb, ty - la + std::cos(A) * la - std::sin(A) * std::sin(B) * lb,
            tz + std::cos(B) * lb - lb};
}

constexpr double kPrinted = 5e-4 + 1e-9;

std::string machine_path(const std::string& name) { return std::string(XLATE5_MACHINE_DIR_FOR_TESTS) + "/" + name + ".toml"; }

const char* kGood =
    "; a small tool-space file\n"
    "G28\n"
    "G92 A-168\n"
    "G1 A0 B0\n"
    "G1 X100 Y100 Z10 F1200\n"
    "G1 A30 E1\n"
    "G1 X120 B-20 E2\n";

}  // namespace

TEST_CASE("cli: a good file translates with exit code 0, from -i and from standard input") {
    TempDir d;
    const fs::path in = d.write("good.gcode", kGood);
    const Result r = run(d, "-m rw2 --no-segment -i " + quote(in.string()));
    CHECK(r.code == 0);
    CHECK(r.err.empty());
    const auto lines = body_lines(r.out, "rw2");
    REQUIRE(lines.size() == 7);
    CHECK(lines[0] == "; a small tool-space file");
    CHECK(lines[1] == "G28");
    CHECK(lines[2] == "G92 A-168");
    // Last line: tip (120, 100, 10), A 30, B -20 per eq. 4.5.
    const auto w = words_of(lines[6]);
    const Xyz e = eq45(120, 100, 10, 30, -20, 26.5);
    CHECK(std::abs(w.at('X') - e.x) <= kPrinted);
    CHECK(std::abs(w.at('Y') - e.y) <= kPrinted);
    CHECK(std::abs(w.at('Z') - e.z) <= kPrinted);
    CHECK(w.at('B') == -20);
    CHECK(w.at('E') == 2);

    const Result s = run(d, "-m rw2 --no-segment", kGood);
    CHECK(s.code == 0);
    CHECK(s.out == r.out);
}

TEST_CASE("cli: bad G-code exits 1 with file:line:column: on standard error") {
    TempDir d;
    const fs::path in = d.write("bad.gcode", "G1 X1 Y1 Z1 A0 B0\nM104 S200\nG1 X1 Q5\nG1 X2\n");
    const Result r = run(d, "-m rw2 --no-segment -i " + quote(in.string()));
    CHECK(r.code == 1);
    CHECK(contains(r.err, in.string() + ":3:7:"));
    CHECK(contains(r.err, "Q"));

    const Result s = run(d, "-m rw2", "G1 X1 Y1 Z1 A0 B0\n\nG1 Xnan\n");
    CHECK(s.code == 1);
    CHECK(contains(s.err, "<stdin>:3:"));
}

TEST_CASE("cli: X1.5e-05 is refused with file:line:column; declared compact, it is X1.5 and E-05") {
    TempDir d;
    // rw2, G49: joint words go to the firmware as they are, so the output shows the reading.
    const std::string body = "G1 X10 Y10 Z10 A0 B0 F600\nG1 X1.5e-05\n";
    const fs::path in = d.write("exp.gcode", "G49\n" + body);
    Result r = run(d, "-m rw2 -i " + quote(in.string()));
    CHECK(r.code == 1);
    CHECK(r.out.empty());
    CHECK(contains(r.err, in.string() + ":3:8: 'X1.5e-05' is ambiguous"));
    CHECK(contains(r.err, "X1.5 e-05"));
    // The same file declared compact (a line of its own), or the flag: X1.5 with a 5 mm retract,
    // E passed on as it was written.
    const fs::path declared = d.write("declared.gcode", "; xlate5: compact-words\nG49\n" + body);
    for (const std::string& args : {"-m rw2 -i " + quote(declared.string()), "-m rw2 --compact-words -i " + quote(in.string())}) {
        CAPTURE(args);
        r = run(d, args);
        CHECK(r.code == 0);
        const auto lines = lines_of(r.out);
        REQUIRE(!lines.empty());
        CHECK(lines.back() == "G1 X1.5 E-05");
    }
    // Without the declaration, the fix the message names reads the same.
    r = run(d, "-m rw2", "G49\nG1 X10 Y10 Z10 A0 B0 F600\nG1 X1.5 e-05\n");
    CHECK(r.code == 0);
    CHECK(lines_of(r.out).back() == "G1 X1.5 E-05");
}

TEST_CASE("cli: with -o, bad input leaves no output file and an existing one unchanged") {
    TempDir d;
    const fs::path in = d.write("bad.gcode", "G1 X1 Y1 Z1 A0 B0\nG1 X2\nG1 B-101\n");
    const fs::path out = d.path / "out.gcode";
    Result r = run(d, "-m rw2 -i " + quote(in.string()) + " -o " + quote(out.string()));
    CHECK(r.code == 1);
    CHECK(contains(r.err, ":3:"));
    CHECK_FALSE(fs::exists(out));
    CHECK(d.entries() == std::vector<std::string>{"bad.gcode"});  // no temporary file left behind

    const std::string old = "previous content\n";
    d.write("out.gcode", old);
    r = run(d, "-m rw2 -i " + quote(in.string()) + " -o " + quote(out.string()));
    CHECK(r.code == 1);
    CHECK(read(out) == old);
    CHECK(d.entries() == std::vector<std::string>{"bad.gcode", "out.gcode"});

    // A good file replaces it.
    const fs::path good = d.write("good.gcode", kGood);
    r = run(d, "-m rw2 --no-segment -i " + quote(good.string()) + " -o " + quote(out.string()));
    CHECK(r.code == 0);
    CHECK(r.out.empty());
    CHECK(body_lines(read(out), "rw2").size() == 7);
    CHECK(d.entries() == std::vector<std::string>{"bad.gcode", "good.gcode", "out.gcode"});
}

TEST_CASE("cli: -o follows a symlink and keeps it; keeps the mode (and, as root, the owner) of the file it replaces") {
    TempDir d;
    const fs::path good = d.write("good.gcode", kGood);
    const Result expected = run(d, "-m rw2 --no-segment -i " + quote(good.string()));
    REQUIRE(expected.code == 0);

    const fs::path real = d.write("real.gcode", "old\n");
    fs::permissions(real, fs::perms(0640));
    const bool root = ::geteuid() == 0;
    if (root) REQUIRE(::chown(real.c_str(), 1234, 2345) == 0);
    fs::create_symlink("real.gcode", d.path / "link.gcode");
    Result r = run(d, "-m rw2 --no-segment -i " + quote(good.string()) + " -o " + quote((d.path / "link.gcode").string()));
    CHECK(r.code == 0);
    CHECK(fs::is_symlink(d.path / "link.gcode"));
    CHECK(fs::read_symlink(d.path / "link.gcode") == "real.gcode");
    CHECK(read(real) == expected.out);
    struct stat st {};
    REQUIRE(::stat(real.c_str(), &st) == 0);
    CHECK((st.st_mode & 07777) == 0640);
    if (root) {
        CHECK(st.st_uid == 1234u);
        CHECK(st.st_gid == 2345u);
    }
    // A dangling link: the file it names is created, the link kept.
    fs::create_symlink("later.gcode", d.path / "dangling.gcode");
    r = run(d, "-m rw2 --no-segment -i " + quote(good.string()) + " -o " + quote((d.path / "dangling.gcode").string()));
    CHECK(r.code == 0);
    CHECK(fs::is_symlink(d.path / "dangling.gcode"));
    CHECK(read(d.path / "later.gcode") == expected.out);
    CHECK(d.entries() == std::vector<std::string>{"dangling.gcode", "good.gcode", "later.gcode", "link.gcode", "real.gcode"});
}

TEST_CASE("cli: -o over a read-only file exits 4 and leaves it as it was") {
    TempDir d;
    const fs::path good = d.write("good.gcode", kGood);
    const fs::path ro = d.write("ro.gcode", "keep me\n");
    fs::permissions(ro, fs::perms(0444));
    // As root too: a file without any write permission is not replaced.
    const Result r = run(d, "-m rw2 -i " + quote(good.string()) + " -o " + quote(ro.string()));
    CHECK(r.code == 4);
    CHECK(contains(r.err, "read-only (mode 0444)"));
    CHECK(read(ro) == "keep me\n");
    CHECK(d.entries() == std::vector<std::string>{"good.gcode", "ro.gcode"});
}

TEST_CASE("cli: -o to a FIFO or a device node writes into it and never replaces it") {
    TempDir d;
    const fs::path good = d.write("good.gcode", kGood);
    const Result expected = run(d, "-m rw2 --no-segment -i " + quote(good.string()));
    REQUIRE(expected.code == 0);
    const fs::path fifo = d.path / "fifo";
    REQUIRE(::mkfifo(fifo.c_str(), 0600) == 0);
    std::string received;
    std::thread reader([&] {
        const int fd = ::open(fifo.c_str(), O_RDONLY);
        if (fd < 0) return;
        char buf[4096];
        for (ssize_t n; (n = ::read(fd, buf, sizeof buf)) > 0;) received.append(buf, std::size_t(n));
        ::close(fd);
    });
    const Result r = run(d, "-m rw2 --no-segment -i " + quote(good.string()) + " -o " + quote(fifo.string()));
    // Had the translator never opened the FIFO, this releases the reader (the test fails, not hangs).
    if (const int unblock = ::open(fifo.c_str(), O_WRONLY | O_NONBLOCK); unblock >= 0) ::close(unblock);
    reader.join();
    CHECK(r.code == 0);
    CHECK(received == expected.out);
    struct stat st {};
    REQUIRE(::lstat(fifo.c_str(), &st) == 0);
    CHECK(S_ISFIFO(st.st_mode));
    CHECK(d.entries() == std::vector<std::string>{"fifo", "good.gcode"});

    // A character device (a copy of /dev/null's node): only root may make one.
    if (::geteuid() != 0) {
        MESSAGE("not root: the device-node case is skipped");
        return;
    }
    const fs::path null = d.path / "null";
    REQUIRE(::mknod(null.c_str(), S_IFCHR | 0666, ::makedev(1, 3)) == 0);
    const Result n = run(d, "-m rw2 -i " + quote(good.string()) + " -o " + quote(null.string()));
    CHECK(n.code == 0);
    REQUIRE(::lstat(null.c_str(), &st) == 0);
    CHECK(S_ISCHR(st.st_mode));
    CHECK(st.st_rdev == ::makedev(1, 3));
    CHECK(d.entries() == std::vector<std::string>{"fifo", "good.gcode", "null"});
}

TEST_CASE("cli: -o /dev/stdout writes to standard output and leaves /dev alone") {
    TempDir d;
    const fs::path good = d.write("good.gcode", kGood);
    const Result expected = run(d, "-m rw2 --no-segment -i " + quote(good.string()));
    REQUIRE(expected.code == 0);
    const bool was_link = fs::is_symlink("/dev/stdout");
    const Result r = run(d, "-m rw2 --no-segment -i " + quote(good.string()) + " -o /dev/stdout");
    CHECK(r.code == 0);
    CHECK(r.out == expected.out);
    CHECK(fs::is_symlink("/dev/stdout") == was_link);
    for (const auto& e : fs::directory_iterator("/dev")) CHECK_FALSE(contains(e.path().filename().string(), ".xlate5-"));
}

TEST_CASE("cli: -i F -o F translates F in place from its original content") {
    TempDir d;
    const fs::path good = d.write("good.gcode", kGood);
    const Result expected = run(d, "-m rw2 --no-segment -i " + quote(good.string()));
    REQUIRE(expected.code == 0);
    const Result r = run(d, "-m rw2 --no-segment -i " + quote(good.string()) + " -o " + quote(good.string()));
    CHECK(r.code == 0);
    CHECK(read(good) == expected.out);
    CHECK(d.entries() == std::vector<std::string>{"good.gcode"});
}

TEST_CASE("cli: SIGINT or SIGTERM while translating into -o leaves no temporary file") {
    for (const int sig : {SIGINT, SIGTERM}) {
        CAPTURE(sig);
        TempDir d;
        const fs::path fifo = d.path / "in.fifo", out = d.path / "out.gcode";
        REQUIRE(::mkfifo(fifo.c_str(), 0600) == 0);
        const pid_t pid = ::fork();
        REQUIRE(pid >= 0);
        if (pid == 0) {
            const int null = ::open("/dev/null", O_WRONLY);
            ::dup2(null, 2);
            ::execl(XLATE5_BINARY, XLATE5_BINARY, "-m", "rw2", "-i", fifo.c_str(), "-o", out.c_str(), static_cast<char*>(nullptr));
            ::_exit(127);
        }
        // The translator blocks on its input, which stays open and half-written.
        const int w = ::open(fifo.c_str(), O_WRONLY);
        REQUIRE(w >= 0);
        const std::string start = "G28\nG1 X100 Y100 Z10 F1200\n";
        REQUIRE(::write(w, start.data(), start.size()) == ssize_t(start.size()));
        bool temp_seen = false;
        for (int i = 0; i < 1000 && !temp_seen; ++i) {
            for (const auto& name : d.entries()) temp_seen = temp_seen || contains(name, "out.gcode.xlate5-");
            if (!temp_seen) ::usleep(10000);
        }
        CHECK(temp_seen);
        REQUIRE(::kill(pid, sig) == 0);
        int status = 0;
        REQUIRE(::waitpid(pid, &status, 0) == pid);
        ::close(w);
        CHECK(WIFSIGNALED(status));
        if (WIFSIGNALED(status)) CHECK(WTERMSIG(status) == sig);
        CHECK(d.entries() == std::vector<std::string>{"in.fifo"});
    }
}

TEST_CASE("cli: an input file that cannot be opened exits 4") {
    TempDir d;
    const Result r = run(d, "-m rw2 -i " + quote((d.path / "missing.gcode").string()));
    CHECK(r.code == 4);
    CHECK(contains(r.err, "missing.gcode"));
}

TEST_CASE("cli: an unknown machine exits 3") {
    TempDir d;
    Result r = run(d, "-m nosuchmachine", "G1 X1\n");
    CHECK(r.code == 3);
    CHECK(contains(r.err, "nosuchmachine"));
    r = run(d, "-m " + quote((d.path / "absent.toml").string()), "G1 X1\n");
    CHECK(r.code == 3);
    CHECK(contains(r.err, "absent.toml"));
}

TEST_CASE("cli: a broken machine file exits 3 naming the path, the line and the key") {
    TempDir d;
    std::string text = read(machine_path("rw2"));
    REQUIRE(!text.empty());
    // Misspell the first joint's "type" key and find the line it is on.
    const std::size_t at = text.find("type = \"linear\"");
    REQUIRE(at != std::string::npos);
    text.replace(at, 4, "tpye");
    const int line = 1 + int(std::count(text.begin(), text.begin() + std::ptrdiff_t(at), '\n'));
    const fs::path toml = d.write("typo.toml", text);
    Result r = run(d, "-m " + quote(toml.string()), "G1 X1\n");
    CHECK(r.code == 3);
    CAPTURE(r.err);
    CHECK(contains(r.err, toml.string() + ":" + std::to_string(line)));
    CHECK(contains(r.err, "tpye"));

    // A TOML syntax error.
    std::string broken = read(machine_path("rw2"));
    const std::size_t axis = broken.find("axis = [1, 0, 0]");
    REQUIRE(axis != std::string::npos);
    broken.replace(axis, 16, "axis = [1, 0, 0");
    const int line2 = 1 + int(std::count(broken.begin(), broken.begin() + std::ptrdiff_t(axis), '\n'));
    const fs::path toml2 = d.write("syntax.toml", broken);
    r = run(d, "-m " + quote(toml2.string()), "G1 X1\n");
    CHECK(r.code == 3);
    CAPTURE(r.err);
    CHECK(contains(r.err, toml2.string()));
    // The parser may report the error on the unclosed line or the one after it.
    const std::string at1 = ':' + std::to_string(line2), at2 = ':' + std::to_string(line2 + 1);
    CHECK((contains(r.err, at1) || contains(r.err, at2)));
}

TEST_CASE("cli: bad options exit 2") {
    TempDir d;
    CHECK(run(d, "-m rw2 --no-such-option", "").code == 2);
    CHECK(run(d, "", "G1 X1\n").code == 2);  // no machine
    CHECK(run(d, "-m rw2 --mode G99", "").code == 2);
    CHECK(run(d, "-m rw2 --extruder-letter 12", "").code == 2);
    CHECK(run(d, "-m rw2 --set la", "").code == 2);
    CHECK(run(d, "-m rw2 --set la=abc", "").code == 2);
    CHECK(run(d, "-m rw2 --preview-form G99 --inverse", "").code == 2);
    CHECK(run(d, "-m rw2 --tolerance -1", "").code == 2);
}

TEST_CASE("cli: 'machines' lists the bundled machines") {
    TempDir d;
    const Result r = run(d, "machines");
    CHECK(r.code == 0);
    std::vector<std::string> names;
    for (const auto& l : lines_of(r.out)) {
        std::istringstream s(l);
        std::string name;
        s >> name;
        names.push_back(name);
        CHECK_FALSE(contains(l, "broken"));
    }
    for (const std::string m : {"rw2", "pentarod", "wpi5", "koc5", "addin4", "xyzac-trt"}) {
        CAPTURE(m);
        CHECK(std::find(names.begin(), names.end(), m) != names.end());
    }
}

TEST_CASE("cli: --set la=29 changes the output per eq. 4.5") {
    TempDir d;
    const std::string in = "G1 X100 Y100 Z10 A90 B0\nG1 A45 B30\n";
    for (double la : {26.5, 29.0}) {
        CAPTURE(la);
        const Result r = run(d, la == 29.0 ? "-m rw2 --no-segment --set la=29" : "-m rw2 --no-segment", in);
        REQUIRE(r.code == 0);
        const auto lines = body_lines(r.out, "rw2");
        REQUIRE(lines.size() == 2);
        auto w = words_of(lines[0]);
        Xyz e = eq45(100, 100, 10, 90, 0, la);
        CHECK(std::abs(w.at('X') - e.x) <= kPrinted);  // table 4.1 with la = 29: 129, 71
        CHECK(std::abs(w.at('Y') - e.y) <= kPrinted);
        w = words_of(lines[1]);
        e = eq45(100, 100, 10, 45, 30, la);
        CHECK(std::abs(w.at('X') - e.x) <= kPrinted);
        CHECK(std::abs(w.at('Y') - e.y) <= kPrinted);
        CHECK(std::abs(w.at('Z') - e.z) <= kPrinted);
    }
}

TEST_CASE("cli: --set of a parameter the machine does not have exits 3") {
    TempDir d;
    const Result r = run(d, "-m rw2 --set nosuch=1", "G1 X1\n");
    CHECK(r.code == 3);
    CHECK(contains(r.err, "nosuch"));
}

TEST_CASE("cli: --inverse turns joint-space G-code into tool space") {
    TempDir d;
    // Joints from eq. 4.5 for tip (100, 100, 10), A = 30, B = 10, printed to 3 decimals.
    const Xyz j = eq45(100, 100, 10, 30, 10, 26.5);
    char line[160];
    std::snprintf(line, sizeof line, "G1 X%.3f Y%.3f Z%.3f A30 B10 F1200\n", j.x, j.y, j.z);
    const Result r = run(d, "-m rw2 --inverse", line);
    REQUIRE(r.code == 0);
    const auto lines = body_lines(r.out, "rw2", "tool space");
    REQUIRE(lines.size() == 1);
    const auto w = words_of(lines[0]);
    CHECK(std::abs(w.at('X') - 100) <= 2e-3);
    CHECK(std::abs(w.at('Y') - 100) <= 2e-3);
    CHECK(std::abs(w.at('Z') - 10) <= 2e-3);
    CHECK(w.at('A') == 30);
    CHECK(w.at('B') == 10);
    CHECK(w.at('F') == 1200);

    // G43.5 preview: the tool axis u = (sin B cos A, -sin B sin A, cos B) of rw2.toml.
    const Result v = run(d, "-m rw2 --inverse --preview-form G43.5", line);
    REQUIRE(v.code == 0);
    const auto wv = words_of(body_lines(v.out, "rw2", "tool space").at(0));
    CHECK(std::abs(wv.at('I') - std::sin(rad(10)) * std::cos(rad(30))) < 1e-6);
    CHECK(std::abs(wv.at('J') + std::sin(rad(10)) * std::sin(rad(30))) < 1e-6);
    CHECK(std::abs(wv.at('K') - std::cos(rad(10))) < 1e-6);
}

TEST_CASE("cli: a joint value that cannot be written (1e200, beyond 1e9, not finite) exits 1 naming the line; no garbage output") {
    TempDir d;
    // Joint space in, through FK with an absurd link length: X would be about 1e200.
    Result r = run(d, "-m rw2 --inverse --set la=1e200", "G28\nG1 X100 Y100 Z10 A30 B10 F1200\n");
    CHECK(r.code == 1);
    CHECK(contains(r.err, "<stdin>:2:"));
    CHECK(contains(r.err, "cannot be written"));
    CHECK(r.out.find("G1") == std::string::npos);  // nothing of the line; only what came before it
    for (const char c : r.out) CHECK(((c >= 0x20 && c < 0x7F) || c == '\n'));
    // A huge number in a move: under G20 the lexer's 1e9 becomes 2.54e10 mm of extrusion and feed.
    r = run(d, "-m rw2 --no-segment", "G1 X100 Y100 Z10 A0 B0 F1200\nG20\nG1 X4 E1000000000\n");
    CHECK(r.code == 1);
    CHECK(contains(r.err, "<stdin>:3:"));
    CHECK(contains(r.err, "word E"));
    CHECK(contains(r.err, "2.54e+10"));
    // (On rw2 without its X Y Z speed limits, which would slow the piece to a writable F.)
    std::string unlimited = read(machine_path("rw2"));
    for (const char* limit : {"max_feed = 30000", "max_feed = 300 "})
        for (std::size_t at = unlimited.find(limit); at != std::string::npos; at = unlimited.find(limit, at + 3)) unlimited.insert(at, "# ");
    const fs::path rw2_unlimited = d.write("rw2_unlimited.toml", unlimited);
    r = run(d, "-m " + quote(rw2_unlimited.string()) + " --no-segment", "G1 X100 Y100 Z10 A0 B0 F1200\nG20\nG1 X4 F1000000000\n");
    CHECK(r.code == 1);
    CHECK(contains(r.err, "<stdin>:3:"));
    CHECK(contains(r.err, "word F"));
    // A huge compensation term: X corrected by 1e300 mm.
    const fs::path comp = d.write("huge.toml", "[[compensation]]\njoint = \"X\"\nby = \"A\"\nfourier = { a0 = 1e300 }\n");
    r = run(d, "-m rw2 --no-segment --compensation " + quote(comp.string()), "G1 X100 Y100 Z10 A0 B0 F1200\n");
    CHECK(r.code == 1);
    CHECK(contains(r.err, "<stdin>:1:"));
    CHECK(contains(r.err, "word X: a value of -1e+300 cannot be written"));
    CHECK(r.out.empty());
}

TEST_CASE("cli: --version prints a version") {
    TempDir d;
    const Result r = run(d, "--version");
    CHECK(r.code == 0);
    // "xlate5 MAJOR.MINOR.PATCH"
    REQUIRE(r.out.rfind("xlate5 ", 0) == 0);
    int dots = 0;
    std::size_t i = 7;
    for (; i < r.out.size() && (std::isdigit(static_cast<unsigned char>(r.out[i])) || r.out[i] == '.'); ++i) dots += r.out[i] == '.';
    CHECK(i > 7);
    CHECK(dots == 2);
}

TEST_CASE("cli: calibrate fit recovers a known series from noisy measurements, within the noise") {
    TempDir d;
    // e(A) = 0.3 - 0.25 cos A - 0.4 sin A + 0.1 cos 2A, sampled every 15 degrees, +-0.01 noise.
    std::string csv = "# angle, error\n";
    for (int a = -165; a <= 165; a += 15) {
        const double r = rad(a), noise = 0.01 * std::sin(a * 12.9898);
        char line[64];
        std::snprintf(line, sizeof line, "%d,%.6f\n", a, 0.3 - 0.25 * std::cos(r) - 0.4 * std::sin(r) + 0.1 * std::cos(2 * r) + noise);
        csv += line;
    }
    const fs::path table = d.write("t.csv", csv);
    const Result r = run(d, "calibrate fit " + quote(table.string()) + " --order 2 --joint Z --by A");
    REQUIRE(r.code == 0);
    CAPTURE(r.out);
    double a0 = 0, c1 = 0, c2 = 0, s1 = 0, s2 = 0, residual = 0;
    REQUIRE(std::sscanf(r.out.c_str(), "# fitted to %*d points of %*s largest residual %lf", &residual) == 1);
    const auto at = r.out.find("fourier = { a0 = ");
    REQUIRE(at != std::string::npos);
    REQUIRE(std::sscanf(r.out.c_str() + at, "fourier = { a0 = %lf, cos = [%lf, %lf], sin = [%lf, %lf] }", &a0, &c1, &c2, &s1, &s2) == 5);
    CHECK(std::abs(a0 - 0.3) < 0.01);
    CHECK(std::abs(c1 + 0.25) < 0.01);
    CHECK(std::abs(s1 + 0.4) < 0.01);
    CHECK(std::abs(c2 - 0.1) < 0.01);
    CHECK(std::abs(s2) < 0.01);
    CHECK(residual <= 0.0101);
    // A malformed line names itself.
    const fs::path bad = d.write("bad.csv", "0,1\n15 2\n");
    const Result b = run(d, "calibrate fit " + quote(bad.string()));
    CHECK(b.code == 1);
    CHECK(contains(b.err, "bad.csv:2:1:"));
}

TEST_CASE("cli: calibrate offset gives Grutle (Oslo 2015) eq. 5.5; calibrate centre the circle through the dots") {
    TempDir d;
    // Grutle (Oslo 2015) sec. 5.2.1's procedure: touch at Y = 30 and Y = -30.
    const Result r = run(d, "calibrate offset " + quote(d.write("t.csv", "30, 0.5\n-30, -0.5\n").string()));
    REQUIRE(r.code == 0);
    double offset = 0;
    REQUIRE(std::sscanf(r.out.c_str(), "rotary offset %lf", &offset) == 1);
    CHECK(offset == doctest::Approx(std::atan(0.5 / 30) * 180 / kPi).epsilon(1e-6));
    const Result c = run(d, "calibrate centre " + quote(d.write("c.csv", "12,3\n2,13\n-8,3\n2,-7\n").string()));
    REQUIRE(c.code == 0);
    double cx = 0, cy = 0, radius = 0;
    REQUIRE(std::sscanf(c.out.c_str(), "rotation centre (%lf, %lf), radius %lf", &cx, &cy, &radius) == 3);
    CHECK(cx == doctest::Approx(2).epsilon(1e-6));
    CHECK(cy == doctest::Approx(3).epsilon(1e-6));
    CHECK(radius == doctest::Approx(10).epsilon(1e-6));
    CHECK(run(d, "calibrate centre " + quote(d.write("few.csv", "1,2\n3,4\n").string())).code == 1);
}

TEST_CASE("cli: calibrate pivots fits rw2's la from tips measured per eq. 4.5 and writes a copy") {
    TempDir d;
    // Tips the real head (la = 29) puts at these joints, from eq. 4.5 solved for the tip.
    std::string csv;
    const double la = 29, lb = 47.9;
    const double js[][5] = {{100, 100, 20, 30, 10}, {110, 95, 22, -60, 20}, {90, 105, 18, 120, -30}, {100, 100, 20, -150, 40}, {105, 110, 21, 75, -15}};
    for (const auto& j : js) {
        const double A = rad(j[3]), B = rad(j[4]);
        char line[200];
        std::snprintf(line, sizeof line, "%g,%g,%g,%g,%g,%.6f,%.6f,%.6f\n", j[0], j[1], j[2], j[3], j[4],
                      j[0] - std::sin(A) * la - std::cos(A) * std::sin(B) * lb, j[1] + la - std::cos(A) * la + std::sin(A) * std::sin(B) * lb,
                      j[2] - std::cos(B) * lb + lb);
        csv += line;
    }
    const fs::path out = d.path / "rw2-cal.toml";
    const Result r = run(d, "--machine rw2 calibrate pivots " + quote(d.write("m.csv", csv).string()) + " --fit la -o " + quote(out.string()));
    REQUIRE(r.code == 0);
    CAPTURE(r.out);
    double fitted = 0, was = 0;
    REQUIRE(std::sscanf(r.out.c_str(), "la = %lf   (was %lf)", &fitted, &was) == 2);
    CHECK(fitted == doctest::Approx(29).epsilon(1e-6));
    CHECK(was == doctest::Approx(26.5));
    CHECK(contains(read(out), "la = 29.000000"));
    // Never over the original.
    CHECK(run(d, "--machine rw2 calibrate pivots " + quote((d.path / "m.csv").string()) + " --fit la -o " + quote(machine_path("rw2"))).code == 2);
}

TEST_CASE("cli: machine names are found in the user's directory before the shipped ones, and the shipped ones beside the program") {
    TempDir d;
    const std::string in = "G1 X100 Y100 Z10 A90 B0\nG1 A45 B30\n";
    std::string rw2 = read(machine_path("rw2"));
    const std::size_t at = rw2.find("\nla = 26.5");
    REQUIRE(at != std::string::npos);
    rw2.replace(at, 10, "\nla = 29");
    fs::create_directories(d.path / "config/xlate5/machines");
    std::ofstream(d.path / "config/xlate5/machines/mine.toml") << rw2;
    fs::create_directories(d.path / "home/.config/xlate5/machines");
    std::ofstream(d.path / "home/.config/xlate5/machines/rw2.toml") << rw2;
    // No override directory: what a user's shell has.
    const std::string user = "env -u XLATE5_MACHINES HOME=" + quote((d.path / "nohome").string()) + " XDG_CONFIG_HOME=" +
                             quote((d.path / "config").string()) + " ";
    const std::string home = "env -u XLATE5_MACHINES -u XDG_CONFIG_HOME HOME=" + quote((d.path / "home").string()) + " ";

    const Result shipped = run(d, "-m rw2 --no-segment", in), la29 = run(d, "-m rw2 --no-segment --set la=29", in);
    REQUIRE(shipped.code == 0);
    REQUIRE(la29.code == 0);
    REQUIRE(shipped.out != la29.out);
    // $XDG_CONFIG_HOME/xlate5/machines: a new name, and the shipped names still there.
    const Result mine = run(d, "-m mine --no-segment", in, user);
    CHECK(mine.code == 0);
    CHECK(mine.out == la29.out);
    const Result still = run(d, "-m rw2 --no-segment", in, user);
    CHECK(still.code == 0);
    CHECK(still.out == shipped.out);  // found beside the program: build/share/xlate5/machines
    const Result list = run(d, "machines", "", user);
    CHECK(list.code == 0);
    const auto listed = [&list](const std::string& name) {
        const auto lines = lines_of(list.out);
        return std::any_of(lines.begin(), lines.end(), [&name](const std::string& l) { return l.rfind(name + " ", 0) == 0; });
    };
    CHECK(listed("mine"));
    CHECK(listed("rw2"));
    // ~/.config/xlate5/machines without XDG_CONFIG_HOME; a file there replaces the shipped one.
    const Result replaced = run(d, "-m rw2 --no-segment", in, home);
    CHECK(replaced.code == 0);
    CHECK(replaced.out == la29.out);
}

TEST_CASE("cli: the argument parser's errors start with xlate5: and name the nearest option or command") {
    TempDir d;
    struct Case {
        std::string args, want;
    };
    for (const Case& c : std::vector<Case>{{"-m rw2 --tolerence 0.1", "did you mean '--tolerance'?"},
                                           {"--tolerence=0.1 -m rw2", "did you mean '--tolerance'?"},
                                           {"-m rw2 --machnie rw2", "did you mean '--machine'?"},
                                           {"machnes", "unknown command 'machnes'; did you mean 'machines'?"},
                                           {"serv --printer sim", "did you mean 'serve'?"},
                                           {"serve --prot /dev/ttyUSB0", "did you mean '--port'?"},
                                           {"serve --printer sim --sim-fualt drop=0.1", "did you mean '--sim-fault'?"},
                                           {"calibrate fti t.csv", "did you mean 'fit'?"},
                                           {"calibrate fit t.csv --ordre 2", "did you mean '--order'?"}}) {
        CAPTURE(c.args);
        const Result r = run(d, c.args);
        CHECK(r.code == 2);
        CHECK(r.err.rfind("xlate5: ", 0) == 0);
        CHECK(contains(r.err, c.want));
        CHECK(r.out.empty());
    }
    // Nothing near: no guess.
    const Result far = run(d, "-m rw2 --zqxwv 1");
    CHECK(far.code == 2);
    CHECK(contains(far.err, "unknown option '--zqxwv'"));
    CHECK_FALSE(contains(far.err, "did you mean"));
    // A command's own options are suggested only after it.
    const Result top = run(d, "-m rw2 --prot x");
    CHECK(top.code == 2);
    CHECK_FALSE(contains(top.err, "--port"));
    // Every refusal of the parser, not only unknown names.
    for (const std::string args : {"-m rw2 --tolerance", "-m rw2 --preview-form G99", "calibrate", "calibrate fit", "-m rw2 --tolerance -1",
                                   "serve --baud 12"}) {
        CAPTURE(args);
        const Result r = run(d, args);
        CHECK(r.code == 2);
        CHECK(r.err.rfind("xlate5: ", 0) == 0);
    }
}

TEST_CASE("cli: numbers out of range are refused with their bounds written plainly") {
    TempDir d;
    for (const std::string value : {"-1", "0", "10.5", "nan", "inf", "1e999", "abc"}) {
        CAPTURE(value);
        const Result r = run(d, "-m rw2 --tolerance " + value, "G1 X1\n");
        CHECK(r.code == 2);
        CHECK(contains(r.err, "--tolerance"));
        CHECK(contains(r.err, "above 0 and at most 10 (mm)"));
        CHECK_FALSE(contains(r.err, "000000"));  // no %f of the double range
    }
    CHECK(run(d, "-m rw2 --no-segment --tolerance 10", "G1 X100 Y100 Z10 A0 B0\n").code == 0);
    const Result order = run(d, "calibrate fit t.csv --order 13");
    CHECK(order.code == 2);
    CHECK(contains(order.err, "from 1 to 12"));
    const Result baud = run(d, "serve --printer sim --baud 9999999999999");
    CHECK(baud.code == 2);
    CHECK(contains(baud.err, "from 300 to 4000000"));
    // The help says the same.
    const Result help = run(d, "--help");
    CHECK(contains(help.out, "above 0 and at most 10 mm"));
    CHECK_FALSE(contains(help.out, "179769"));
}

TEST_CASE("cli: serve --help gives every option's default") {
    TempDir d;
    const Result r = run(d, "serve --help");
    REQUIRE(r.code == 0);
    int options = 0;
    // An option's line, and its description when CLI11 puts that on the next line.
    const auto lines = lines_of(r.out);
    for (std::size_t i = 0; i < lines.size(); ++i) {
        const std::string& l = lines[i];
        if (l.rfind("  -", 0) != 0 || contains(l, "--help")) continue;
        ++options;
        CAPTURE(l);
        const std::string next = i + 1 < lines.size() && lines[i + 1].rfind("      ", 0) == 0 ? lines[i + 1] : "";
        CHECK((contains(l, "(default: ") || contains(next, "(default: ")));
    }
    CHECK(options >= 20);
    // The documented ones (config/xlate5.toml, docs/service.md).
    CHECK(contains(r.out, "(default: 115200)"));
    CHECK(contains(r.out, "(default: /run/xlate5/printer)"));
    // The machine has no default (issue 36): it decides every joint move.
    CHECK(contains(r.out, "(default: none: required unless --config gives one)"));
    CHECK_FALSE(contains(r.out, "(default: rw2)"));
}

TEST_CASE("cli: serve without a port or --printer sim is an error, not a silent simulator") {
    TempDir d;
    const std::string pty = (d.path / "printer").string();
    for (const std::string& args :
         std::vector<std::string>{"serve --no-pty --tcp 127.0.0.1:0", "serve --pty " + quote(pty), "serve --printer serial --pty " + quote(pty)}) {
        CAPTURE(args);
        const Result r = run(d, args);
        CHECK(r.code == 2);
        CHECK(r.err.rfind("xlate5: ", 0) == 0);
        CHECK(contains(r.err, "--port DEVICE"));
        CHECK(contains(r.err, "--printer sim"));
        CHECK_FALSE(fs::exists(fs::symlink_status(pty)));
    }
}

TEST_CASE("cli: what a user reads names its sources by author, place and year, never by a corpus number") {
    TempDir d;
    // "seed 001" and the like: a number that means something only to whoever collected the sources.
    const auto numbered = [](const std::string& text) {
        for (std::size_t at = text.find("seed "); at != std::string::npos; at = text.find("seed ", at + 1))
            if (at + 5 < text.size() && std::isdigit(static_cast<unsigned char>(text[at + 5]))) return text.substr(at, 40);
        return std::string();
    };
    std::vector<std::pair<std::string, std::string>> texts;
    for (const std::string args : {"--help", "machines", "serve --help", "ports --help", "calibrate --help", "calibrate fit --help",
                                   "calibrate plate --help", "calibrate offset --help", "calibrate pivots --help", "calibrate centre --help", "pose --help",
                                   "--man-page"}) {
        const Result r = run(d, args);
        REQUIRE(r.code == 0);
        texts.emplace_back("xlate5 " + args, r.out);
    }
    const fs::path source = fs::path(XLATE5_MACHINE_DIR_FOR_TESTS).parent_path();
    for (const fs::path& dir : std::vector<fs::path>{source, source / "docs", source / "machines", source / "machines/compensation", source / "config"})
        for (const auto& e : fs::directory_iterator(dir))
            if (e.is_regular_file() && (e.path().extension() == ".md" || e.path().extension() == ".toml"))
                texts.emplace_back(e.path().string(), read(e.path()));
    CHECK(texts.size() > 20);
    for (const auto& [where, text] : texts) {
        CAPTURE_BINDING(where);
        CHECK(numbered(text).empty());
    }
    CHECK(contains(run(d, "machines").out, "Andersons, Twente 2023"));
}

namespace {

// "label K=v K=v ..." lines of `xlate5 pose` as label -> (key -> value).
std::map<std::string, std::map<std::string, double>> pose_lines(const std::string& out) {
    std::map<std::string, std::map<std::string, double>> r;
    for (const auto& line : lines_of(out)) {
        std::istringstream words(line);
        std::string label, w;
        words >> label;
        while (words >> w)
            if (const auto eq = w.find('='); eq != std::string::npos && eq > 0) r[label][w.substr(0, eq)] = std::stod(w.substr(eq + 1));
    }
    return r;
}

std::string triple(double a, double b, double c) {
    char s[120];
    std::snprintf(s, sizeof s, "%.9g,%.9g,%.9g", a, b, c);
    return s;
}

}  // namespace

TEST_CASE("cli: pose gives pentarod's tip and tool axis per Grutle's pseudo code 4.1") {
    TempDir d;
    for (const auto& [x, y, z, a, c] : std::vector<std::array<double, 5>>{{0, 0, 0, 30, 20}, {12.5, -7, 3, -45, 170}, {40, 30, 20, 80, -95}}) {
        CAPTURE_BINDING(a);
        CAPTURE_BINDING(c);
        char args[200];
        std::snprintf(args, sizeof args, "-m pentarod pose X=%g Y=%g Z=%g A=%g C=%g", x, y, z, a, c);
        const Result r = run(d, args);
        REQUIRE(r.code == 0);
        const auto p = pose_lines(r.out);
        // u = R_z(-C) R_x(-A) z = (sin A sin C, sin A cos C, cos A); the tip at machine XYZ is
        // p = R_z(-C) R_x(-A) (X, Y, Z) (machine XYZ = R_x(A) R_z(C) p).
        const double A = rad(a), C = rad(c);
        CHECK(std::abs(p.at("axis").at("I") - std::sin(A) * std::sin(C)) <= 1e-6);
        CHECK(std::abs(p.at("axis").at("J") - std::sin(A) * std::cos(C)) <= 1e-6);
        CHECK(std::abs(p.at("axis").at("K") - std::cos(A)) <= 1e-6);
        const double y1 = std::cos(A) * y + std::sin(A) * z, z1 = -std::sin(A) * y + std::cos(A) * z;  // R_x(-A)
        const double x2 = std::cos(C) * x + std::sin(C) * y1, y2 = -std::sin(C) * x + std::cos(C) * y1;  // R_z(-C)
        CHECK(std::abs(p.at("tip").at("X") - x2) <= 1e-4);
        CHECK(std::abs(p.at("tip").at("Y") - y2) <= 1e-4);
        CHECK(std::abs(p.at("tip").at("Z") - z1) <= 1e-4);
    }
    // Joints not named stay at home (all 0 on pentarod): the tip is the origin, the axis vertical.
    const auto home = pose_lines(run(d, "-m pentarod pose").out);
    CHECK(std::abs(home.at("tip").at("Z")) <= 1e-9);
    CHECK(home.at("axis").at("K") == 1);
}

TEST_CASE("cli: pose round trips: joints -> tip and axis -> joints -> the same tip and axis, on every shipped machine") {
    TempDir d;
    struct Case {
        const char* machine;
        const char* joints;
    };
    for (const Case& k : {Case{"pentarod", "X=10 Y=-20 Z=15 A=35 C=-60"}, Case{"rw2", "X=100 Y=90 Z=20 A=30 B=25"},
                          Case{"koc5", "B=20 C=40"}, Case{"wpi5", ""}, Case{"xyzac-trt", "X=5 Y=5 Z=30 A=20 C=130"}}) {
        CAPTURE(k.machine);
        const Result f = run(d, std::string("-m ") + k.machine + " pose " + k.joints);
        REQUIRE(f.code == 0);
        const auto p = pose_lines(f.out);
        const auto& tip = p.at("tip");
        const auto& axis = p.at("axis");
        const Result i = run(d, std::string("-m ") + k.machine + " pose --tip " + triple(tip.at("X"), tip.at("Y"), tip.at("Z")) + " --axis " +
                                    triple(axis.at("I"), axis.at("J"), axis.at("K")));
        REQUIRE(i.code == 0);
        const auto q = pose_lines(i.out);
        // The joints it found reach the pose asked for (FK of the printed joints, independently run).
        std::string joints;
        for (const auto& [name, v] : q.at("joints")) joints += " " + name + "=" + std::to_string(v);
        const auto back = pose_lines(run(d, std::string("-m ") + k.machine + " pose" + joints).out);
        for (const char* c : {"X", "Y", "Z"}) CHECK(std::abs(back.at("tip").at(c) - tip.at(c)) <= 2e-3);
        for (const char* c : {"I", "J", "K"}) CHECK(std::abs(back.at("axis").at(c) - axis.at(c)) <= 1e-4);
        // Started from the original joints, the nearest solution is those joints.
        const auto same = pose_lines(run(d, std::string("-m ") + k.machine + " pose " + k.joints + " --tip " +
                                                triple(tip.at("X"), tip.at("Y"), tip.at("Z")) + " --axis " +
                                                triple(axis.at("I"), axis.at("J"), axis.at("K")))
                                         .out);
        for (const auto& [name, v] : p.at("joints")) {
            CAPTURE_BINDING(name);
            CHECK(std::abs(same.at("joints").at(name) - v) <= 2e-3);
        }
    }
}

TEST_CASE("cli: pose refuses an unknown joint, a zero axis and an unreachable pose, saying why") {
    TempDir d;
    Result r = run(d, "-m pentarod pose Q=3");
    CHECK(r.code == 2);
    CHECK(contains(r.err, "xlate5: "));
    CHECK(contains(r.err, "no joint Q (it has X, Y, Z, A, C)"));
    r = run(d, "-m pentarod pose A=abc");
    CHECK(r.code == 2);
    r = run(d, "-m pentarod pose --tip 0,0,0 --axis 0,0,0");
    CHECK(r.code == 2);
    CHECK(contains(r.err, "0,0,0"));
    r = run(d, "-m pentarod pose --tip 0,0 --axis 0,0,1");
    CHECK(r.code == 2);
    // Pentarod's A stops at 90 degrees: an axis pointing down cannot be reached.
    r = run(d, "-m pentarod pose --tip 0,0,10 --axis 0,0,-1");
    CHECK(r.code == 1);
    CHECK(contains(r.err, "pose"));
    CHECK(r.out.empty());
    // Joints outside their limits are shown, with a note.
    r = run(d, "-m pentarod pose A=120");
    CHECK(r.code == 0);
    CHECK(contains(r.out, "A=120.0000 is outside its limits -90 to 90"));
}

namespace {

// Everything readable on `fd`: waits up to `first_ms` for the first bytes (a loaded machine, a
// sanitizer build), then reads until `quiet_ms` pass without more, or the end.
std::string drain(int fd, int first_ms, int quiet_ms = 300) {
    std::string got;
    char b[4096];
    for (;;) {
        pollfd p{fd, POLLIN, 0};
        if (::poll(&p, 1, got.empty() ? first_ms : quiet_ms) <= 0) return got;
        const ssize_t n = ::read(fd, b, sizeof b);
        if (n <= 0) return got;
        got.append(b, std::size_t(n));
    }
}

void put_all(int fd, const std::string& s) {
    for (std::size_t done = 0; done < s.size();) {
        const ssize_t n = ::write(fd, s.data() + done, s.size() - done);
        REQUIRE(n > 0);
        done += std::size_t(n);
    }
}

// A travel move and printing moves after it, `count` times: the look-back releases each group's
// output when the next travel move arrives.
std::string groups(int count, int& e) {
    std::string s;
    for (int g = 0; g < count; ++g) {
        s += "G1 X" + std::to_string(100 + g % 20) + " Y100 Z10 A0 B0 F1200\n";
        for (int i = 0; i < 5; ++i) s += "G1 X" + std::to_string(101 + g % 20) + "." + std::to_string(i) + " Y101 E" + std::to_string(++e) + "\n";
    }
    return s;
}

}  // namespace

TEST_CASE("cli: as a filter, output is written before the input ends; the progress bar shows only on a terminal") {
    int in[2], out[2];
    REQUIRE(::pipe(in) == 0);
    REQUIRE(::pipe(out) == 0);
    const int master = ::posix_openpt(O_RDWR | O_NOCTTY);
    REQUIRE(master >= 0);
    REQUIRE(::grantpt(master) == 0);
    REQUIRE(::unlockpt(master) == 0);
    const std::string slave = ::ptsname(master);
    const pid_t pid = ::fork();
    REQUIRE(pid >= 0);
    if (pid == 0) {
        const int tty = ::open(slave.c_str(), O_RDWR | O_NOCTTY);
        ::dup2(in[0], 0), ::dup2(out[1], 1), ::dup2(tty, 2);
        ::close(in[0]), ::close(in[1]), ::close(out[0]), ::close(out[1]), ::close(tty), ::close(master);
        ::execl(XLATE5_BINARY, "xlate5", "-m", "rw2", static_cast<char*>(nullptr));
        ::_exit(127);
    }
    ::close(in[0]);
    ::close(out[1]);
    int e = 0;
    put_all(in[1], groups(3, e));
    // The input is still open: the first groups' joints must arrive anyway.
    const std::string early = drain(out[0], 10000);
    CHECK(lines_of(early).size() >= 6);
    // After the first second, each block read draws the bar on the terminal.
    for (int k = 0; k < 4; ++k) {
        std::this_thread::sleep_for(std::chrono::milliseconds(400));
        put_all(in[1], groups(2, e));
        CHECK(!drain(out[0], 10000).empty());
    }
    ::close(in[1]);
    const std::string rest = drain(out[0], 10000, 10000);
    int status = 0;
    REQUIRE(::waitpid(pid, &status, 0) == pid);
    CHECK(WIFEXITED(status));
    CHECK(WEXITSTATUS(status) == 0);
    const std::string tty = drain(master, 2000);
    ::close(out[0]);
    ::close(master);
    CAPTURE(tty);
    CHECK(contains(tty, "xlate5: "));
    CHECK(contains(tty, " lines, "));
    // Cleared at the end: the prompt (or an error) starts on a clean line.
    CHECK(tty.size() >= 4);
    CHECK(tty.substr(tty.size() - 4) == "\r\033[K");

    // The same translation with standard error in a file: nothing but the output.
    TempDir d;
    e = 0;
    const Result r = run(d, "-m rw2", groups(12, e));
    CHECK(r.code == 0);
    CHECK(r.err.empty());
}

namespace {

// The first `chromium` on PATH, or "". None in the sanitizer tree: the page is written there
// under the sanitizers all the same, but Chromium is not instrumented, and it rendering the page
// (the release tree's run) would take a third of the program's time there.
constexpr const char* kNoChromium = kAddressSanitized ? "sanitizer build: the page is rendered in the release tree"
                                                       : "chromium not installed: the page is not rendered (Debian package chromium)";
std::string find_chromium() {
    if (kAddressSanitized) return "";
    const char* path = std::getenv("PATH");
    std::stringstream dirs(path ? path : "");
    for (std::string dir; std::getline(dirs, dir, ':');)
        if (!dir.empty() && ::access((dir + "/chromium").c_str(), X_OK) == 0) return dir + "/chromium";
    return "";
}

// A count the report gives ("name": N).
long report_count(const std::string& json, const std::string& name) {
    const auto at = json.find("\"" + name + "\": ");
    REQUIRE_MESSAGE(at != std::string::npos, name);
    return std::stol(json.substr(at + name.size() + 4));
}

// The page's summary of its marks, as the report's counts say it must read.
std::string marks_summary(const std::string& json) {
    return std::to_string(report_count(json, "pole_crossings")) + " pole crossings, " + std::to_string(report_count(json, "unwinds")) +
           " unwinds, " + std::to_string(report_count(json, "branch_changes")) + " branch changes, " +
           std::to_string(report_count(json, "rezeros")) + " re-zeros marked";
}

int occurrences(const std::string& hay, const std::string& what) {
    int c = 0;
    for (auto at = hay.find(what); at != std::string::npos; at = hay.find(what, at + 1)) ++c;
    return c;
}

// The page's DOM once headless Chromium ran its script.
std::string rendered_dom(const std::string& chromium, const fs::path& profile, const std::string& url) {
    const std::string cmd = quote(chromium) + " --headless --no-sandbox --disable-gpu --disable-background-networking --disable-component-update "
                            "--disable-sync --no-first-run --window-size=1000,1400 --user-data-dir=" + quote(profile.string()) +
                            " --dump-dom " + quote(url) + " 2>/dev/null";
    std::string dom;
    if (FILE* p = ::popen(cmd.c_str(), "r")) {
        char b[4096];
        for (std::size_t n; (n = std::fread(b, 1, sizeof b, p)) > 0;) dom.append(b, n);
        ::pclose(p);
    }
    return dom;
}

// The marks listed in the page's data: kind and written move number.
std::vector<std::pair<std::string, long>> page_marks(const std::string& html) {
    std::vector<std::pair<std::string, long>> marks;
    const auto start = html.find("\"marks\": [");
    REQUIRE(start != std::string::npos);
    const auto end = html.find("], \"joints\"", start);
    for (auto at = html.find("[\"", start); at != std::string::npos && at < end; at = html.find("[\"", at + 1)) {
        const auto q = html.find('"', at + 2), close = html.find(']', at);
        const auto comma = html.rfind(',', close);
        marks.emplace_back(html.substr(at + 2, q - at - 2), std::stol(html.substr(comma + 1, close - comma - 1)));
    }
    return marks;
}

}  // namespace

TEST_CASE("cli: --preview writes one self-contained page, bounded in size, that headless Chromium loads and draws") {
    TempDir d;
    const fs::path source = fs::path(XLATE5_MACHINE_DIR_FOR_TESTS).parent_path();
    const std::string example = (source / "examples/rw2_flared_wall.gcode").string();
    const fs::path page = d.path / "wall.html";
    const Result r = run(d, "-m rw2 -i " + quote(example) + " -o " + quote((d.path / "out.gcode").string()) + " --preview " + quote(page.string()) +
                                " --report " + quote((d.path / "wall.json").string()));
    REQUIRE(r.code == 0);
    const std::string html = read(page);
    REQUIRE(!html.empty());
    // The marks are the report's events: the first travel from home turns A by 150 degrees in one
    // line but ends where the file put it (A150), so it is no unwind, in the report or on the page.
    const std::string json = read(d.path / "wall.json");
    CHECK(contains(html, marks_summary(json)));
    CHECK(page_marks(html).size() == std::size_t(report_count(json, "pole_crossings") + report_count(json, "unwinds") +
                                                 report_count(json, "branch_changes") + report_count(json, "rezeros")));
    double a_before_printing = NAN, largest_turn = 0;  // A where the travel ends, as written; its largest step
    for (const auto& l : lines_of(read(d.path / "out.gcode"))) {
        if (l.rfind("G0 ", 0) != 0 && l.rfind("G1 ", 0) != 0) continue;
        const auto w = words_of(l);
        if (w.count('E')) break;
        if (w.count('A')) {
            if (!std::isnan(a_before_printing)) largest_turn = std::max(largest_turn, std::abs(w.at('A') - a_before_printing));
            a_before_printing = w.at('A');
        }
    }
    MESSAGE("the travel from home ends at A " << a_before_printing << ", largest step " << largest_turn << " degrees");
    CHECK(a_before_printing == 150);
    CHECK(report_count(json, "unwinds") + report_count(json, "branch_changes") == 0);
    CHECK(page_marks(html).empty());
    // Nothing from the network: no external script, style, image or font. three.js and its
    // OrbitControls are inlined word for word from Debian's libjs-three (their text names an XML
    // namespace and a paper by URL, never loaded): the page without them names no URL at all.
    std::string own = html;
    for (const char* lib : {"/usr/share/javascript/three/three.min.js", "/usr/share/javascript/three/examples/js/controls/OrbitControls.js"}) {
        const std::string text = read(lib);
        REQUIRE(!text.empty());
        const auto at = own.find(text);
        REQUIRE(at != std::string::npos);
        own.erase(at, text.size());
    }
    CHECK(!contains(own, "http://"));
    CHECK(!contains(own, "https://"));
    CHECK(!contains(own, " src="));
    CHECK(!contains(own, " href="));
    // Every written joint line is counted.
    std::size_t moves = 0;
    for (const auto& l : lines_of(read(d.path / "out.gcode")))
        if (l.rfind("G1 ", 0) == 0 || l.rfind("G0 ", 0) == 0) ++moves;
    CHECK(contains(html, std::to_string(moves) + " moves written"));

    // Bounded: a long file is thinned to at most 4000 points, evenly.
    int e = 0;
    const Result big = run(d, "-m rw2 -o /dev/null --preview " + quote((d.path / "big.html").string()), groups(8000, e));
    REQUIRE(big.code == 0);
    const std::string bightml = read(d.path / "big.html");
    const auto shown_at = bightml.find(" shown");
    REQUIRE(shown_at != std::string::npos);
    const auto comma = bightml.rfind(", ", shown_at);
    const long shown = std::stol(bightml.substr(comma + 2));
    CHECK(shown <= 4000);
    CHECK(shown >= 2000);
    // The data stay under 1.5 MB beside the inlined three.js (docs/limits.md: the page is at most 4 MB).
    CHECK(bightml.size() < 1500000 + std::strlen(xlate5::three_js::kSource) + std::strlen(xlate5::three_js::kOrbitControls));

    const std::string chromium = find_chromium();
    if (chromium.empty()) {
        MESSAGE(kNoChromium);
        return;
    }
    const std::string flags = " --headless --no-sandbox --disable-gpu --disable-background-networking --disable-component-update "
                              "--disable-sync --no-first-run --window-size=1000,1400 --enable-unsafe-swiftshader --enable-logging=stderr --v=0 ";
    auto shot = [&](const fs::path& html_file, const std::string& png, const std::string& profile, std::string& log) {
        const std::string cmd = quote(chromium) + flags + "--user-data-dir=" + quote((d.path / profile).string()) + " --screenshot=" +
                                quote((d.path / png).string()) + " " + quote("file://" + html_file.string()) + " >" +
                                quote((d.path / (png + ".log")).string()) + " 2>&1";
        const int status = std::system(cmd.c_str());
        log = read(d.path / (png + ".log"));
        return status;
    };
    std::string log;
    REQUIRE(shot(page, "page.png", "profile1", log) == 0);
    CAPTURE(log);
    // Whatever reaches the console (errors, uncaught exceptions) is logged as a CONSOLE line; the
    // page writes nothing there.
    CHECK(!contains(log, "Uncaught"));
    // Software WebGL (SwiftShader) reports its own read-back of the screenshot as a console
    // message; nothing else may reach the console.
    std::size_t console = 0;
    for (const auto& l : lines_of(log))
        if (contains(l, ":CONSOLE") && !contains(l, "GL Driver Message")) ++console;
    CHECK(console == 0);
    CHECK(contains(log, "bytes written to file"));
    // The script ran to its end (it marks the title last).
    const std::string dom_cmd = quote(chromium) + flags + "--user-data-dir=" + quote((d.path / "profile2").string()) + " --dump-dom " +
                                quote("file://" + page.string()) + " 2>/dev/null";
    std::string dom;
    if (FILE* p = ::popen(dom_cmd.c_str(), "r")) {
        char b[4096];
        for (std::size_t n; (n = std::fread(b, 1, sizeof b, p)) > 0;) dom.append(b, n);
        ::pclose(p);
    }
    CHECK(contains(dom, "(drawn)</title>"));
    CHECK(occurrences(dom, "data-kind=") == int(page_marks(html).size()));
    // Not blank: a page of the same size with nothing drawn compresses to far fewer bytes.
    const fs::path blank = d.write("blank.html", "<!DOCTYPE html><html><body style=\"margin:0;background:#fff\"></body></html>\n");
    std::string blank_log;
    REQUIRE(shot(blank, "blank.png", "profile3", blank_log) == 0);
    const auto drawn = fs::file_size(d.path / "page.png"), empty = fs::file_size(d.path / "blank.png");
    MESSAGE("screenshot " << drawn << " bytes, blank page " << empty << " bytes");
    CHECK(drawn > 4 * empty);
}

TEST_CASE("cli: --preview marks pole crossings and re-zeros where the written output has them, as the report counts them, and colours by deviation") {
    // koc5 (B tilts, C turns the table without limit): a printed helix whose tool axis passes the
    // pole twice, then travel moves that wind C past five turns, re-zeroed with G92 by a travel.
    TempDir d;
    std::string in = "G43.5\nM83\n";
    auto fmt = [](double v) {
        char b[32];
        std::snprintf(b, sizeof b, "%.6f", v);
        return std::string(b);
    };
    for (int i = 0; i < 600; ++i) {
        const double s = i * 0.01, tilt = rad(3 * std::sin(s * 1.5)), az = 0.3;
        in += "G1 X" + fmt(20 * std::cos(s)) + " Y" + fmt(20 * std::sin(s)) + " Z" + fmt(1 + 0.001 * i) + " I" + fmt(std::sin(tilt) * std::cos(az)) +
              " J" + fmt(std::sin(tilt) * std::sin(az)) + " K" + fmt(std::cos(tilt)) + (i == 0 ? " F1500\n" : " E0.01\n");
    }
    for (int i = 1; i <= 80; ++i) {  // travel: the axis's azimuth turns 30 degrees a move
        const double tilt = rad(20), az = rad(i * 30.0);
        in += "G1 X0 Y0 Z20 I" + fmt(std::sin(tilt) * std::cos(az)) + " J" + fmt(std::sin(tilt) * std::sin(az)) + " K" + fmt(std::cos(tilt)) + "\n";
    }
    const fs::path page = d.path / "marks.html", out = d.path / "marks.gcode";
    const fs::path report = d.path / "marks.json";
    const Result r = run(d, "-m koc5 -o " + quote(out.string()) + " --preview " + quote(page.string()) + " --report " + quote(report.string()), in);
    REQUIRE_MESSAGE(r.code == 0, r.err);
    // The reference, from the written lines: B changing sign (the other branch across the pole)
    // and G92 renaming C; each mark sits on the written move B arrives on the other side, or
    // the one the G92 follows.
    int poles = 0, unwinds = 0, sign = 0;
    long move = -1;
    std::vector<long> pole_moves, rezero_moves;
    for (const auto& l : lines_of(read(out))) {
        if (l.rfind(';', 0) == 0) continue;  // the output's header
        const auto w = words_of(l);
        if (l.rfind("G92 ", 0) == 0 && w.count('C')) ++unwinds, rezero_moves.push_back(move);
        if (l.rfind("G1 ", 0) == 0 || l.rfind("G0 ", 0) == 0) ++move;
        if ((l.rfind("G1 ", 0) == 0 || l.rfind("G0 ", 0) == 0) && w.count('B') && w.at('B') != 0) {
            const int now = w.at('B') > 0 ? 1 : -1;
            if (sign != 0 && now != sign) ++poles, pole_moves.push_back(move);
            sign = now;
        }
    }
    MESSAGE("written: " << poles << " pole crossings, " << unwinds << " re-zeroes");
    REQUIRE(poles >= 2);
    REQUIRE(unwinds >= 1);
    const std::string html = read(page), json = read(report);
    // The page, the report and the written joints agree.
    CHECK(report_count(json, "pole_crossings") == poles);
    CHECK(report_count(json, "rezeros") == unwinds);
    CHECK(contains(html, marks_summary(json)));
    CHECK(contains(html, std::to_string(poles) + " pole crossings, 0 unwinds, 0 branch changes, " + std::to_string(unwinds) + " re-zeros marked"));
    std::vector<long> page_poles, page_rezeros, page_others;
    for (const auto& [kind, at] : page_marks(html)) (kind == "pole" ? page_poles : kind == "rezero" ? page_rezeros : page_others).push_back(at);
    CHECK(page_poles.size() == std::size_t(poles));
    CHECK(page_others.empty());
    CHECK(page_rezeros == rezero_moves);
    // A pole crossing is marked on the last written piece of the move that crossed: at or after
    // the line where B arrives on the other side, before the next crossing.
    for (std::size_t i = 0; i < page_poles.size() && i < pole_moves.size(); ++i) {
        CHECK(page_poles[i] >= pole_moves[i]);
        if (i + 1 < pole_moves.size()) CHECK(page_poles[i] < pole_moves[i + 1]);
    }
    CHECK(contains(html, "<option value=\"dev\">deviation</option>"));

    const std::string chromium = find_chromium();
    if (chromium.empty()) {
        MESSAGE(kNoChromium);
        return;
    }
    // Opened on the deviation view, the script draws the marks and lists them, and runs to its end.
    const std::string dom = rendered_dom(chromium, d.path / "profile", "file://" + page.string() + "#deviation");
    CHECK(contains(dom, "(drawn)</title>"));
    CHECK(occurrences(dom, "data-kind=\"pole\"") == poles);
    CHECK(occurrences(dom, "data-kind=\"rezero\"") == unwinds);
    CHECK(occurrences(dom, "data-kind=") == poles + unwinds);
}

TEST_CASE("cli: --preview marks the look-back's unwind that the written lines split into small pieces, as the report counts it") {
    // rw2 prints round its azimuth past A's limit (168): the layer change at A150 is turned onto
    // the other branch (A - 180, B -> -B) by the look-back, its rotaries turning over many
    // written pieces, none 150 degrees.
    TempDir d;
    std::string in;
    for (const auto& l : unwinding_print(false)) in += l + "\n";
    const fs::path page = d.path / "unwind.html", out = d.path / "unwind.gcode", report = d.path / "unwind.json";
    const Result r = run(d, "-m rw2 -o " + quote(out.string()) + " --preview " + quote(page.string()) + " --report " + quote(report.string()), in);
    REQUIRE_MESSAGE(r.code == 0, r.err);
    // The reference, from the written joints: B changing sign (passing upright does not count),
    // and the written move the travel ends on (the last before printing starts again).
    int flips = 0, sign = 0;
    long move = -1, flip_move = -1, travel_end = -1;
    double largest_turn = 0, a_before = 0;
    bool have_a = false;
    for (const auto& l : lines_of(read(out))) {
        if (l.rfind("G1 ", 0) != 0 && l.rfind("G0 ", 0) != 0) continue;
        ++move;
        const auto w = words_of(l);
        if (w.count('A')) {
            if (have_a) largest_turn = std::max(largest_turn, std::abs(w.at('A') - a_before));
            a_before = w.at('A'), have_a = true;
        }
        if (flip_move >= 0 && travel_end < 0 && w.count('E')) travel_end = move - 1;
        if (w.count('B') && std::abs(w.at('B')) > 1) {
            const int now = w.at('B') > 0 ? 1 : -1;
            if (sign != 0 && now != sign) ++flips, flip_move = move;
            sign = now;
        }
    }
    MESSAGE("written: " << flips << " branch flips, largest turn of A in one line " << largest_turn << " degrees");
    REQUIRE(flips == 1);
    CHECK(largest_turn < 150);  // split: no line of it looks like an unwind by itself
    REQUIRE(travel_end >= flip_move);
    const std::string html = read(page), json = read(report);
    CHECK(report_count(json, "branch_changes") == flips);
    CHECK(report_count(json, "pole_crossings") == 0);
    CHECK(contains(html, marks_summary(json)));
    const auto marks = page_marks(html);
    REQUIRE(marks.size() == 1);
    CHECK(marks[0].first == "branch");
    CHECK(marks[0].second == travel_end);

    const std::string chromium = find_chromium();
    if (chromium.empty()) {
        MESSAGE(kNoChromium);
        return;
    }
    const std::string dom = rendered_dom(chromium, d.path / "profile", "file://" + page.string());
    CHECK(contains(dom, "(drawn)</title>"));
    CHECK(occurrences(dom, "data-kind=\"branch\"") == flips);
    CHECK(occurrences(dom, "data-kind=") == flips);
}

TEST_CASE("cli: nothing written for Marlin is longer than 95 characters: display text is shortened and said, a file name refused") {
    // Marlin reads a line up to 95 characters and the rest as a new line (Marlin's queue.cpp):
    // the tail of a long M117 would run as a raw, untranslated joint move.
    TempDir dir;
    const std::string text(90, 'x');
    const auto in = dir.write("long.gcode", "G28\nM117 " + text + "G1 Z0 F9000\nM118 E1 " + text + "\nG1 Z250\n");
    const auto r = run(dir, "--machine rw2 -i " + quote(in.string()) + " -o " + quote((dir.path / "o.gcode").string()));
    CHECK(r.code == 0);
    const std::string out = read(dir.path / "o.gcode");
    for (const auto& l : lines_of(out)) {
        CAPTURE(l);
        CHECK(l.size() <= 95);
    }
    CHECK(contains(out, "M117 " + text.substr(0, 90) + "\n"));  // 95 characters: the text's head, no G1
    CHECK_FALSE(contains(out, "G1 Z0 F9000"));
    CHECK(contains(r.err, "long.gcode:2: note: M117's text shortened to 95 characters"));
    CHECK(contains(r.err, "long.gcode:3: note: M118's text shortened"));
    // A file name cannot be shortened: refused, nothing written.
    const auto bad = dir.write("name.gcode", "M23 /" + std::string(100, 'd') + ".gco\n");
    const auto b = run(dir, "--machine rw2 -i " + quote(bad.string()) + " -o " + quote((dir.path / "n.gcode").string()));
    CHECK(b.code == 1);
    CHECK(contains(b.err, "name.gcode:1:96: this line would be written with 109 characters"));
    CHECK_FALSE(fs::exists(dir.path / "n.gcode"));
}

TEST_CASE("cli: an empty input says so on stderr and gives the header alone, exit 0") {
    TempDir dir;
    const auto r = run(dir, "--machine rw2", "");
    CHECK(r.code == 0);
    CHECK(contains(r.err, "<stdin>: note: the input is empty"));
    CHECK(lines_of(r.out).size() == 1);
}
