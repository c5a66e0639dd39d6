// SPDX-License-Identifier: GPL-3.0-or-later
// The slicer's M73 and time lines rewritten from the pre-flight estimate of the written file:
// against a reference summed here from the pre-flight's executed blocks, on a file PrusaSlicer
// slices at test time and on the corpus's Cura file; every other byte as without the rewrite.
#include <doctest/doctest.h>

#include "helpers.hpp"
#include "translators/inspect/preflight.hpp"
#include "translators/inspect/slicer_times.hpp"

#include <cmath>
#include <cstdlib>
#include <sstream>
#include <string>
#include <vector>

using namespace xlate5;
using namespace xlate5::test;

namespace {

// A number after `key` in `line` (NaN when absent).
double value_after(const std::string& line, const std::string& key) {
    const auto at = line.find(key);
    if (at == std::string::npos) return std::nan("");
    return std::strtod(line.c_str() + at + key.size(), nullptr);
}

// "1h 32m 30s" -> seconds.
double dhms_seconds(const std::string& s) {
    double total = 0, v = 0;
    std::istringstream in(s);
    std::string word;
    while (in >> word) {
        v = std::strtod(word.c_str(), nullptr);
        const char unit = word.back();
        total += v * (unit == 'd' ? 86400 : unit == 'h' ? 3600 : unit == 'm' ? 60 : 1);
    }
    return total;
}

// The reference: each line's motion time before it, from the pre-flight's blocks as executed.
struct Reference {
    std::vector<double> before;  // by line number (1-based; [0] unused)
    double total = 0;
};
Reference reference(const Machine& m, const std::string& text) {
    Preflight p(m, 115200);
    std::vector<std::pair<std::uint64_t, double>> blocks;
    p.executed = [&](std::uint64_t line, double s) { blocks.emplace_back(line, s); };
    p.scan(text);
    p.finish();
    const auto lines = lines_of(text);
    Reference r;
    r.before.assign(lines.size() + 2, 0.0);
    std::size_t b = 0;
    double sum = 0;
    for (std::size_t l = 1; l < r.before.size(); ++l) {
        while (b < blocks.size() && blocks[b].first < l) sum += blocks[b++].second;
        r.before[l] = sum;
    }
    for (; b < blocks.size(); ++b) sum += blocks[b].second;
    r.total = sum;
    CHECK(r.total == doctest::Approx(p.seconds()).epsilon(1e-12));
    return r;
}

// Translates `input` to a file with and without the rewrite, and to standard output; checks
// every line against the reference. Returns the count of time lines.
std::size_t check_rewrite(const std::string& machine, const std::string& input, bool last_m73_at_end) {
    TempDir d;
    const std::string in = quote(input);
    const auto at = [&](const char* name) { return quote((d.path / name).string()); };
    REQUIRE(run_xlate5(d, "--machine " + machine + " --no-progress -i " + in + " -o " + at("new.gcode")).code == 0);
    REQUIRE(run_xlate5(d, "--machine " + machine + " --no-progress --keep-slicer-times -i " + in + " -o " + at("keep.gcode")).code == 0);
    const RunResult piped = run_xlate5(d, "--machine " + machine + " --no-progress -i " + in);
    REQUIRE(piped.code == 0);
    // The rewrite leaves no temporary file behind.
    CHECK(d.entries() == std::vector<std::string>{"keep.gcode", "new.gcode"});
    const std::string keep = read(d.path / "keep.gcode"), got = read(d.path / "new.gcode");
    CHECK(piped.out == keep);  // a stream keeps the slicer's lines
    const auto a = lines_of(keep), b = lines_of(got);
    REQUIRE(a.size() == b.size());
    const Machine m = load_machine(std::string(XLATE5_MACHINE_DIR_FOR_TESTS) + "/" + machine + ".toml");
    const Reference ref = reference(m, keep);
    REQUIRE(ref.total > 0);
    std::size_t time_lines = 0, changed = 0;
    int last_p = -1;
    double last_r = -1;
    for (std::size_t i = 0; i < a.size(); ++i) {
        const std::string& line = b[i];
        CAPTURE(i + 1);
        CAPTURE(line);
        const SlicerTimeLine kind = slicer_time_line(a[i]);
        if (kind == SlicerTimeLine::None) {
            CHECK(line == a[i]);  // every other line as written without the rewrite
            continue;
        }
        ++time_lines;
        changed += line != a[i];
        const double e = ref.before[i + 1], T = ref.total;
        if (kind == SlicerTimeLine::M73) {
            for (const char* key : {" P", " Q"}) {
                const double p = value_after(line, key);
                if (std::isnan(p)) continue;
                // The percent done truncated; at an exact boundary either side is floating point.
                const double exact = 100 * e / T;
                CHECK((p == std::floor(exact) || std::abs(p - exact) < 1e-9));
                CHECK(int(p) >= last_p);  // monotone
                last_p = int(p);
            }
            for (const char* key : {" R", " S"}) {
                const double r = value_after(line, key);
                if (std::isnan(r)) continue;
                CHECK(r == std::floor((T - e + 0.5) / 60));
                last_r = r;
            }
            // Other words (C, D) and the comment as the slicer wrote them.
            CHECK(line.substr(line.find(';') == std::string::npos ? line.size() : line.find(';')) ==
                  a[i].substr(a[i].find(';') == std::string::npos ? a[i].size() : a[i].find(';')));
        } else if (kind == SlicerTimeLine::Total) {
            CHECK(value_after(line, ";TIME:") == std::round(T));
        } else if (kind == SlicerTimeLine::Elapsed) {
            CHECK(value_after(line, ";TIME_ELAPSED:") == doctest::Approx(e).epsilon(1e-6));
        } else {
            const std::string was = a[i].substr(0, a[i].find(" = ") + 3);
            CHECK(line.rfind(was, 0) == 0);  // the same mode's line
            CHECK(dhms_seconds(line.substr(was.size())) == std::floor(T));
        }
    }
    if (last_m73_at_end) {
        CHECK(last_p == 100);
        CHECK(last_r == 0);
    }
    CHECK(changed > 0);  // the slicer's model and xlate5's differ: the test sees a rewrite
    // --report's pre-flight says the same total.
    REQUIRE(run_xlate5(d, "--machine " + machine + " --no-progress -i " + in + " -o " + at("r.gcode") + " --report " + at("r.json")).code == 0);
    const std::string report = read(d.path / "r.json");
    CHECK(value_after(report, "\"preflight\": {\"seconds\": ") == doctest::Approx(ref.total).epsilon(1e-5));
    CHECK(read(d.path / "r.gcode") == got);
    return time_lines;
}

}  // namespace

TEST_CASE("slicer times: M73's words, Cura's and PrusaSlicer's lines from the elapsed and total seconds") {
    CHECK(slicer_time_line("M73 P10 R5") == SlicerTimeLine::M73);
    CHECK(slicer_time_line("M730") == SlicerTimeLine::None);
    CHECK(slicer_time_line(";TIME:100") == SlicerTimeLine::Total);
    CHECK(slicer_time_line(";TIME_ELAPSED:1.5") == SlicerTimeLine::Elapsed);
    CHECK(slicer_time_line("; estimated printing time (silent mode) = 5s") == SlicerTimeLine::Estimate);
    CHECK(slicer_time_line("; estimated first layer printing time (normal mode) = 5s") == SlicerTimeLine::None);
    // 1000 s in all, 250 s done: 25 %, (750.5 / 60) = 12 minutes left.
    CHECK(retimed_line("M73 P3 R40 C7 ; progress", 250, 1000) == "M73 P25 R12 C7 ; progress");
    CHECK(retimed_line("M73 Q3 S40", 999.99, 1000) == "M73 Q99 S0");
    CHECK(retimed_line("M73 P0", 1000, 1000) == "M73 P100");
    CHECK(retimed_line("M73 P0", 96.252640687, 96.252640687) == "M73 P100");
    CHECK(retimed_line(";TIME:77", 0, 1234.6) == ";TIME:1235");
    CHECK(retimed_line(";TIME_ELAPSED:3.5", 12.25, 100) == ";TIME_ELAPSED:12.250000");
    // No estimate (no motion): the line as written.
    CHECK(retimed_line("M73 P5 R3", 0, 0) == "M73 P5 R3");
    // PrusaSlicer's own footer of the corpus's dino, read back and written again.
    CHECK(time_dhms(dhms_seconds("1h 32m 30s")) == "1h 32m 30s");
    CHECK(time_dhms(2 * 86400 + 5) == "2d 0h 0m 5s");
    CHECK(time_dhms(59.9) == "59s");
    CHECK(retimed_line("; estimated printing time (normal mode) = 1h 32m 30s", 0, 3725.2) ==
          "; estimated printing time (normal mode) = 1h 2m 5s");
}

TEST_CASE("slicer times: the scan and the rewrite agree in any pieces, a last line without a newline too") {
    const Machine m = load_machine(std::string(XLATE5_MACHINE_DIR_FOR_TESTS) + "/rw2.toml");
    const std::string text = ";TIME:5\nM73 P0 R9\nG1 X10 F600\nM73 P50 R1\nG1 X20\n;TIME_ELAPSED:3\nM73 P100 R0";
    std::string whole;
    {
        SlicerTimes t(m, 115200);
        t.scan(text);
        t.finish();
        t.rewrite(text, whole);
        t.rewrite_end(whole);
        CHECK(t.lines() == 5);
    }
    for (std::size_t piece : {1, 2, 3, 7}) {
        SlicerTimes t(m, 115200);
        for (std::size_t i = 0; i < text.size(); i += piece) t.scan(std::string_view(text).substr(i, piece));
        t.finish();
        std::string out;
        for (std::size_t i = 0; i < text.size(); i += piece + 4) t.rewrite(std::string_view(text).substr(i, piece + 4), out);
        t.rewrite_end(out);
        CAPTURE(piece);
        CHECK(out == whole);
    }
    const auto lines = lines_of(whole);
    REQUIRE(lines.size() == 7);
    CHECK(lines[2] == "G1 X10 F600");
    CHECK(lines[6] == "M73 P100 R0");
    CHECK(lines[1].rfind("M73 P0 R", 0) == 0);
}

TEST_CASE("slicer times: a dwell's seconds count where it runs, as in the report's seconds") {
    // The same moves with and without a 90 s dwell between two M73 lines: each line after the
    // dwell is 90 s further on, each before it 90 s further from the end, and the total is the
    // pre-flight's seconds (which counts the dwell, as Marlin's G4 S90 waits after the planner
    // ran out).
    const Machine m = load_machine(std::string(XLATE5_MACHINE_DIR_FOR_TESTS) + "/rw2.toml");
    const std::string moves_a = "M73 P0 R9\nG1 X10 F600\nG1 X40 Y30\n", moves_b = "M73 P50 R1\nG1 X20 F1200\nM73 P100 R0\n";
    auto rewrite = [&](const std::string& text, double& total) {
        SlicerTimes t(m, 115200);
        t.scan(text);
        t.finish();
        std::string out;
        t.rewrite(text, out);
        t.rewrite_end(out);
        total = t.seconds();
        return lines_of(out);
    };
    double plain = 0, dwelt = 0;
    const auto a = rewrite(moves_a + "M400\n" + moves_b, plain);  // the planner runs out there too
    const auto b = rewrite(moves_a + "G4 S90\n" + moves_b, dwelt);
    REQUIRE(plain > 1);
    CHECK(dwelt == doctest::Approx(plain + 90).epsilon(1e-12));
    Preflight report(m, 115200);
    report.scan(moves_a + "G4 S90\n" + moves_b);
    report.finish();
    CHECK(report.seconds() == dwelt);
    // The elapsed time before the second M73: the first two moves alone (the planner runs out
    // before the dwell, so they end at rest either way).
    double first_two = 0;
    rewrite(moves_a, first_two);
    REQUIRE(a.size() == 7);
    REQUIRE(b.size() == 7);
    CHECK(b[0] == retimed_line("M73 P0 R9", 0, plain + 90));
    CHECK(b[0] != a[0]);
    CHECK(b[4] == retimed_line("M73 P50 R1", first_two + 90, plain + 90));
    CHECK(b[6] == "M73 P100 R0");  // at the end: (100 t) / t is 99.99999999999999 for this t
}

TEST_CASE("slicer times: a PrusaSlicer file's M73 follow xlate5's estimate of the written joints") {
    if (std::system("command -v prusa-slicer >/dev/null 2>&1") != 0) {
        MESSAGE("skipped: prusa-slicer is not installed (scripts/install-deps.sh installs it)");
        return;
    }
    TempDir d;
    d.write("cube.stl", cube_stl(20));
    // Marlin 2 flavour with remaining times: M73 P R and Q S, and the footer of both modes.
    REQUIRE(std::system(("cd " + quote(d.path.string()) +
                         " && prusa-slicer --export-gcode --remaining-times --gcode-flavor marlin2 --center 100,100 -o cube.gcode cube.stl "
                         ">/dev/null 2>&1")
                            .c_str()) == 0);
    const std::string sliced = read(d.path / "cube.gcode");
    REQUIRE(sliced.find("\nM73 P0 R") != std::string::npos);
    REQUIRE(sliced.find("\nM73 Q0 S") != std::string::npos);
    CHECK(check_rewrite("rw2", (d.path / "cube.gcode").string(), true) > 100);
}

TEST_CASE("slicer times: the corpus's Cura file gets ;TIME: and each ;TIME_ELAPSED: from the estimate" *
          doctest::skip(corpus_absent())) {
    CHECK(check_rewrite("pentarod", corpus_dir() + "/planar/pi_3mm_deformed_tet_cura-5.8.0.gcode", false) > 100);
}
