// SPDX-License-Identifier: GPL-3.0-or-later
// The offline bounds of docs/limits.md, as a user meets them: the xlate5 binary run on real
// files and on endless ones (/dev/zero) under an address-space limit (prlimit --as) and a
// timeout, so a reader that grows without bound fails the test instead of the machine.
#include <doctest/doctest.h>

#include <sys/wait.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include "daemon/config.hpp"
#include "daemon/link.hpp"
#include "daemon/serve.hpp"
#include "helpers.hpp"
#include "translators/machine/calibration.hpp"
#include "translators/pipeline/keep_out.hpp"
#include "translators/pipeline/lookback.hpp"
#include "translators/machine/machine.hpp"
#include "translators/pipeline/stream.hpp"

using namespace xlate5;
using namespace xlate5::test;
namespace fs = std::filesystem;

namespace {

using Result = RunResult;

// Address space for one run: several times what any bounded reader here needs (each reads at
// most 32 MiB of input and its translation), a small part of what an unbounded read of
// /dev/zero reaches in the timeout. AddressSanitizer reserves terabytes of address space for its
// shadow at start: under it, only the timeout.
// --foreground: a signal sent to timeout reaches the command once (without it, timeout sends it
// to the command and again to its process group, and a second SIGTERM after the drain can land
// once xlate5's handler is gone: exit 143 for a clean stop).
const std::string kLimit = std::string(kAddressSanitized ? "" : "prlimit --as=1073741824 ") + "timeout --foreground 60 ";

// The xlate5 binary with `args` (quoted already), standard output and error to files.
// `prefix` goes before the binary (a limit, a pipe into it); standard input is /dev/null unless
// `from_pipe`.
Result run(const TempDir& dir, const std::string& args, const std::string& prefix = kLimit, bool from_pipe = false) {
    return run_xlate5(dir, args, prefix, RunInput{std::nullopt, from_pipe});
}

}  // namespace

TEST_CASE("bounds: every file read whole is refused past its bound, also an endless one, with file, line and column") {
    TempDir d;
    const std::string zero = "/dev/zero";
    const fs::path gcode = d.write("part.gcode", "G43.4\nG1 X10 Y10 Z10 F1000\n");
    struct Case {
        const char* what;
        std::string args;
        int code;
        std::size_t bound;
    };
    const Case cases[] = {
        {"machine file", "--machine " + zero + " -i " + quote(gcode.string()), 3, kMaxMachineFileBytes},
        {"compensation file", "--machine wpi5 --compensation " + zero + " -i " + quote(gcode.string()), 3, kMaxMachineFileBytes},
        {"keep-out list", "--machine addin4 --keep-out " + zero + " -i " + quote(gcode.string()), 1, kMaxKeepOutBytes},
        {"measurement table", "calibrate plate " + zero, 1, kMaxMeasurementBytes},
        {"measurement table (pivots)", "--machine rw2 calibrate pivots " + zero + " --fit la", 1, kMaxMeasurementBytes},
        {"configuration file", "serve --config " + zero + " --printer sim --check " + quote(gcode.string()), 3, kMaxConfigBytes},
    };
    for (const Case& c : cases) {
        CAPTURE(c.what);
        const Result r = run(d, c.args);
        CAPTURE(r.err);
        CHECK(r.code == c.code);
        // /dev/zero has no line end: the first byte past the bound is on line 1, one column further.
        CHECK(contains(r.err, "/dev/zero:1:" + std::to_string(c.bound + 1) + ": longer than " + std::to_string(c.bound) + " bytes"));
    }
    // A real file one byte past a bound, with line ends: the place is the line and column of that byte.
    std::string text;
    while (text.size() < kMaxKeepOutBytes) text += "# a comment line of a keep-out list, forty-two\n";
    text.resize(kMaxKeepOutBytes + 1);
    std::size_t line = 1, start = 0;
    for (std::size_t i = 0; i < kMaxKeepOutBytes; ++i)
        if (text[i] == '\n') ++line, start = i + 1;
    const fs::path items = d.write("items.csv", text);
    const Result r = run(d, "--machine addin4 --keep-out " + quote(items.string()) + " -i " + quote(gcode.string()));
    CHECK(r.code == 1);
    CHECK(contains(r.err, items.string() + ":" + std::to_string(line) + ":" + std::to_string(kMaxKeepOutBytes - start + 1) + ": longer than"));
    // At the bound exactly, the file is read (and here refused only for what it holds: nothing).
    text.resize(kMaxKeepOutBytes);
    text.back() = '\n';
    d.write("items.csv", text);
    CHECK_FALSE(contains(run(d, "--machine addin4 --keep-out " + quote(items.string()) + " -i " + quote(gcode.string())).err, "longer than"));
}

TEST_CASE("bounds: output is bounded by the input, not only per line; nothing is written past it") {
    TempDir d;
    // 2,000 lines of 100-turn arcs: each within the pieces-per-line bound, 46 KB that wrote
    // over 500 MB before the file's bound.
    std::string text = "G43.4\nG1 X50 Y50 Z10 F1000\n";
    for (int i = 0; i < 2000; ++i) text += "G2 X50 Y50 I10 J0 P100\n";
    const fs::path in = d.write("arcs.gcode", text);
    const fs::path out = d.path / "arcs.out";
    // A file size limit well above the bound: before the bound, the run was killed by it.
    const Result r = run(d, "--machine wpi5 -i " + quote(in.string()) + " -o " + quote(out.string()) + " --no-progress",
                         std::string("sh -c 'ulimit -f 262144; exec \"$0\" \"$@\"' ") + "timeout 120 ");
    CAPTURE(r.err);
    CHECK(r.code == 1);
    // The line where the output passes 16 MiB + 1024 bytes a byte of the input before it, found
    // here from one line's output (every arc line gives the same), at its first column.
    const Result one = run(d, "--machine wpi5 --no-progress -i " + quote(d.write("one.gcode", "G43.4\nG1 X50 Y50 Z10 F1000\nG2 X50 Y50 I10 J0 P100\n").string()));
    REQUIRE(one.code == 0);
    const Result head = run(d, "--machine wpi5 --no-progress -i " + quote(d.write("head.gcode", "G43.4\nG1 X50 Y50 Z10 F1000\n").string()));
    REQUIRE(head.code == 0);
    const std::uint64_t per_line = one.out.size() - head.out.size(), head_bytes = head.out.size();
    std::uint64_t line = 2, consumed = 6 + 22, written = head_bytes;
    while (written <= kOutputFloor + kOutputPerInputByte * consumed) ++line, consumed += 23, written += per_line;
    MESSAGE("each arc line writes " << per_line << " bytes; the bound is passed at line " << line);
    // The look-back holds the last lines' output back (at most LookBack::kMaxHeldBytes of it),
    // so the place is that many lines' output after the estimate at most.
    const auto at = r.err.find("arcs.gcode:");
    REQUIRE(at != std::string::npos);
    const long reported = std::strtol(r.err.c_str() + at + 11, nullptr, 10);
    CHECK(reported >= long(line));
    CHECK(reported <= long(line + LookBack::kMaxHeldBytes / per_line + 1));
    CHECK(contains(r.err, ":" + std::to_string(reported) + ":1: the output would pass its bound"));
    CHECK_FALSE(fs::exists(out));
    CHECK(d.entries().size() == 3);  // the inputs only: no temporary left
    // A real file far below it is untouched (the corpus's largest planar print, when present).
    if (!corpus_absent()) {
        const std::string dino = corpus_dir() + "/planar/dino_prusaslicer-2.9.2.gcode";
        const Result ok = run(d, "--machine wpi5 --no-progress -i " + quote(dino) + " -o " + quote(out.string()));
        CHECK(ok.code == 0);
    }
}

TEST_CASE("bounds: serve --check applies serve's line bound and holds a bounded amount") {
    TempDir d;
    // A line longer than serve takes: the check says serve cancels there, as serve does, and reads no further.
    std::string text = "G28\nG1 X10 Y10 Z10 F1000\nM117 " + std::string(Link::kMaxLine, 'a') + "\nG1 X20\n";
    const fs::path longline = d.write("long.gcode", text);
    const Result r = run(d, "serve --machine wpi5 --printer sim --check " + quote(longline.string()));
    CAPTURE(r.out);
    CHECK(r.code == 1);
    CHECK(contains(r.out, "serve would cancel the print at line 3"));
    CHECK(contains(r.out, "longer than " + std::to_string(Link::kMaxLine) + " bytes (the line-length bound)"));
    CHECK(contains(r.out, "2 input lines -> "));
    // One byte shorter, the line is serve's to take.
    text = "G28\nG1 X10 Y10 Z10 F1000\nM117 " + std::string(Link::kMaxLine - 5, 'a') + "\nG1 X20\n";
    const Result fits = run(d, "serve --machine wpi5 --printer sim --check " + quote(d.write("fits.gcode", text).string()));
    CHECK_FALSE(contains(fits.out, "the line-length bound"));
    CHECK(contains(fits.out, "4 input lines -> "));
    // An endless file: refused at its first line, in bounded memory and time.
    const Result zero = run(d, "serve --machine wpi5 --printer sim --check /dev/zero");
    CAPTURE(zero.err);
    CHECK(zero.code == 1);
    CHECK(contains(zero.out, "serve would cancel the print at line 1"));
    // Endless short lines: refused at the check's line bound.
    const Result lines = run(d, "serve --machine wpi5 --printer sim --check /dev/stdin", std::string("yes '' | ") + kLimit, true);
    CAPTURE(lines.err);
    CHECK(lines.code == 1);
    CHECK(contains(lines.err, "/dev/stdin:" + std::to_string(kMaxCheckLines + 1) + ":1: serve --check holds the file"));
    // A translation past the check's bound: refused where it passes it.
    std::string arcs = "G43.4\nG1 X50 Y50 Z10 F1000\n";
    for (int i = 0; i < 2000; ++i) arcs += "G2 X50 Y50 I10 J0 P100\n";
    const Result big = run(d, "serve --machine wpi5 --printer sim --check " + quote(d.write("arcs.gcode", arcs).string()));
    CAPTURE(big.err);
    CHECK(big.code == 1);
    CHECK(contains(big.err, "serve --check holds the translation in memory: at most " + std::to_string(kMaxCheckOutputBytes)));
}

TEST_CASE("bounds: a reload of an endless machine file keeps the running service and says why") {
    TempDir d;
    // The service as the unit runs it, with the virtual printer; the configuration then names
    // /dev/zero as the machine and the service is told to reload (the issue: 465-650 MB in 8 s,
    // past the unit's MemoryMax=256M).
    const fs::path cfg = d.write("xlate5.toml", "machine = \"wpi5\"\n[firmware]\nport = \"sim\"\n[sender]\npty = \"" + (d.path / "printer").string() + "\"\n");
    const fs::path log = d.path / "serve.log", script = d.path / "reload.sh";
    d.write("reload.sh", "set -u\n" + kLimit + quote(XLATE5_BINARY) + " serve --config " + quote(cfg.string()) + " >" + quote(log.string()) +
                             " 2>&1 &\npid=$!\n"
                             "for i in $(seq 300); do [ -e " + quote((d.path / "printer").string()) + " ] && break; sleep 0.1; done\n"
                             "printf 'machine = \"/dev/zero\"\\n[firmware]\\nport = \"sim\"\\n[sender]\\npty = \"%s\"\\n' " +
                             quote((d.path / "printer").string()) + " >" + quote(cfg.string()) + "\n"
                             "kill -HUP $pid\n"
                             "for i in $(seq 300); do grep -q 'SIGHUP' " + quote(log.string()) + " && break; sleep 0.1; done\n"
                             "kill -0 $pid && echo alive\n"
                             "kill -TERM $pid; wait $pid; echo \"exit $?\"\n");
    const fs::path out = d.path / "script.out";
    REQUIRE(std::system(("sh " + quote(script.string()) + " >" + quote(out.string()) + " 2>&1").c_str()) == 0);
    const std::string said = read(out), logged = read(log);
    CAPTURE(said);
    CAPTURE(logged);
    CHECK(contains(said, "alive\n"));
    CHECK(contains(said, "exit 0\n"));
    CHECK(contains(logged, "/dev/zero:1:" + std::to_string(kMaxMachineFileBytes + 1) + ": longer than"));
    CHECK(contains(logged, "longer than " + std::to_string(kMaxMachineFileBytes) + " bytes, the bound for a machine file"));
    CHECK(contains(logged, "keeping the running configuration"));
}
