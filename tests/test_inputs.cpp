// SPDX-License-Identifier: GPL-3.0-or-later
// The other ways in: CL data (APT / NX CLSF) and waypoint tables, through the input front. Each
// record's target is read here from the file by the test's own parser and compared with forward
// kinematics of the joints the translator wrote for it (not with the translator's own state).
#include <doctest/doctest.h>

#include <cmath>
#include <fstream>
#include <regex>
#include <sys/wait.h>
#include <sstream>

#include "helpers.hpp"
#include "translators/error.hpp"
#include "translators/inputs/input_front.hpp"
#include "translators/pipeline/keep_out.hpp"
#include "translators/kinematics/kinematics.hpp"
#include "translators/machine/machine.hpp"
#include "translators/pipeline/translator.hpp"

using namespace xlate5;
using namespace xlate5::test;

namespace {

std::string corpus(const std::string& rel) { return corpus_dir() + "/" + rel; }

Machine machine(const std::string& name) { return load_machine(std::string(XLATE5_MACHINE_DIR_FOR_TESTS) + "/" + name + ".toml"); }

// The firmware's joints, line after line of output.
struct JointTracker {
    const Machine& m;
    std::vector<double> q;
    explicit JointTracker(const Machine& mm) : m(mm), q(mm.home_joints()) {}
    void apply(const std::string& text) { apply_joint_lines(m, text, q); }
};

struct Record {
    std::uint64_t line;
    Eigen::Vector3d tip, axis;
};

// Every GOTO of a CL file with its modal tool axis, in millimetres (the file's unit given).
std::vector<Record> gotos(const std::string& path, double unit) {
    std::ifstream in(path);
    std::string line;
    std::vector<Record> r;
    Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();
    std::uint64_t n = 0;
    while (std::getline(in, line)) {
        ++n;
        if (line.rfind("GOTO/", 0) != 0) continue;
        std::vector<double> v;
        std::stringstream s(line.substr(5));
        std::string f;
        while (std::getline(s, f, ',')) v.push_back(std::stod(f));
        REQUIRE((v.size() == 3 || v.size() == 6));
        if (v.size() == 6) axis = Eigen::Vector3d(v[3], v[4], v[5]).normalized();
        r.push_back({n, Eigen::Vector3d(v[0], v[1], v[2]) * unit, axis});
    }
    return r;
}

// Feeds a file line by line through an input front (no look-back, so each line's output is its
// own); returns the output of each line.
std::vector<std::string> run_lines(const Kinematics& k, const std::string& path, FrontOptions fo) {
    TranslatorOptions o;
    o.input_name = path;
    Translator t(k, o);
    fo.input_name = path;
    InputFront front(t, fo);
    std::ifstream in(path, std::ios::binary);
    REQUIRE(in);
    std::vector<std::string> out(1);
    std::string line;
    std::uint64_t n = 0;
    while (std::getline(in, line)) {
        out.emplace_back();
        front.feed(line, ++n, out.back());
    }
    out.emplace_back();
    front.finish(n, out.back());
    return out;
}

std::string translate_text(const std::string& machine_name, const std::string& text, FrontOptions fo, const std::string& name = "t.cls") {
    const Machine m = machine(machine_name);
    const Kinematics k(m);
    TranslatorOptions o;
    o.input_name = name;
    Translator t(k, o);
    fo.input_name = name;
    InputFront front(t, fo);
    std::string out;
    std::istringstream in(text);
    std::string line;
    std::uint64_t n = 0;
    while (std::getline(in, line)) front.feed(line, ++n, out);
    front.finish(n, out);
    return out;
}

// The InputError a text raises ("" if none).
InputError error_of(const std::string& machine_name, const std::string& text, FrontOptions fo = {}) {
    try {
        translate_text(machine_name, text, fo);
    } catch (const InputError& e) {
        return e;
    }
    FAIL("no error for:\n" << text);
    return InputError("", 0, 0, "");
}

}  // namespace

// Ends of the joint moves in a whole output, in order (the firmware's joints after each G0/G1).
std::vector<std::vector<double>> move_ends(const Machine& m, const std::string& text) {
    JointTracker tracker(m);
    std::vector<std::vector<double>> ends;
    for (const auto& line : lines_of(text)) {
        tracker.apply(line);
        if (line.rfind("G0 ", 0) == 0 || line.rfind("G1 ", 0) == 0) ends.push_back(tracker.q);
    }
    return ends;
}

TEST_CASE("NX CLSF corpus file: every GOTO's tip and tool axis by FK of the joints written for it" * doctest::skip(corpus_absent())) {
    // xyzac-trt: a trunnion A (+-120 deg) under a C turntable reaches every tilt of this file
    // (at most about 22 deg from +Z, in every direction) with the tip anywhere in the part frame.
    const std::string path = corpus("nx_cldata/APT_Variable_Axis.cls");
    Machine m = machine("xyzac-trt");
    const auto records = gotos(path, 25.4);  // FEDRAT/IPM: the program is in inches
    REQUIRE(records.size() == 348);
    double worst_tip = 0, worst_axis = 0;
    auto check = [&](const Kinematics& k, const std::vector<double>& q, const Record& rec) {
        const Pose p = k.forward(q);
        const double tip = (p.tip - rec.tip).norm();
        const double axis = std::acos(std::clamp(p.axis.dot(rec.axis), -1.0, 1.0)) * 180 / kPi;
        CHECK_MESSAGE(tip < 2e-3, "line " << rec.line);  // the output has 4 decimals
        CHECK_MESSAGE(axis < 5e-3, "line " << rec.line);
        worst_tip = std::max(worst_tip, tip);
        worst_axis = std::max(worst_axis, axis);
    };

    SUBCASE("one joint move per GOTO (no splitting): the i-th move ends at the i-th GOTO") {
        m.motion.segment = false;
        const Kinematics k(m);
        std::string all;
        for (const auto& o : run_lines(k, path, FrontOptions{})) all += o;  // format by content
        const auto ends = move_ends(m, all);
        REQUIRE(ends.size() == records.size());
        for (std::size_t i = 0; i < ends.size(); ++i) check(k, ends[i], records[i]);
    }
    SUBCASE("split within the tolerance: each GOTO line's output ends at its GOTO") {
        const Kinematics k(m);
        const auto out = run_lines(k, path, FrontOptions{InputFormat::Apt});
        JointTracker tracker(m);
        std::size_t checked = 0;
        std::size_t r = 0;
        for (std::size_t line = 1; line < out.size(); ++line) {
            tracker.apply(out[line]);
            while (r < records.size() && records[r].line < line) ++r;
            // GOTOs before the first FEDRAT are held until it (the unit): checked above.
            if (r < records.size() && records[r].line == line && line > 15) check(k, tracker.q, records[r]), ++checked;
        }
        CHECK(checked == records.size() - 2);  // all but the two RAPID GOTOs before FEDRAT/IPM
    }
    MESSAGE("worst tip error " << worst_tip << " mm, worst axis error " << worst_axis << " deg");
}

namespace {

// The G-code lines a CL text stands for (the reader alone).
std::vector<std::string> apt_gcode(const std::string& text, AptOptions o = {}) {
    AptReader reader(o);
    FrontLines out;
    std::istringstream in(text);
    std::string line;
    std::uint64_t n = 0;
    while (std::getline(in, line)) reader.read(line, ++n, out);
    reader.finish(n, out);
    std::vector<std::string> g;
    for (const auto& l : out) g.push_back(l.text);
    return g;
}

std::vector<std::map<char, double>> moves_of(const std::vector<std::string>& g) {
    std::vector<std::map<char, double>> m;
    for (const auto& l : g)
        if (l.rfind("G0 ", 0) == 0 || l.rfind("G1 ", 0) == 0) m.push_back(words_of(l));
    return m;
}

}  // namespace

TEST_CASE("CL records: GOTO with its modal axis, RAPID for one move, FEDRAT forms, units") {
    const auto g = apt_gcode("TOOL PATH/P1,TOOL,T\n$$ a comment\nUNITS/MM\nRAPID\nGOTO/1,2,3,0,0,2\nFEDRAT/MMPM,300\n"
                             "GOTO/4,5,6,3,0,4\nGOTO/7,8,9\nFEDRAT/60,MMPM\nGOTO/1,1,1\nEND-OF-PATH\n");
    const auto mv = moves_of(g);
    REQUIRE(mv.size() == 4);
    CHECK(mv[0].at('G') == 0);
    CHECK(mv[0].at('K') == 1);  // normalised
    CHECK(mv[1].at('G') == 1);  // RAPID was for one GOTO only
    CHECK(mv[1].at('F') == 300);
    CHECK(mv[1].at('I') == doctest::Approx(0.6));
    CHECK(mv[1].at('K') == doctest::Approx(0.8));
    CHECK(mv[2].at('X') == 7);
    CHECK(mv[2].at('I') == doctest::Approx(0.6));  // the axis is modal
    CHECK(mv[2].count('F') == 0);                  // written when it changes
    CHECK(mv[3].at('F') == 60);
    CHECK(std::find(g.begin(), g.end(), "; a comment") != g.end());
    CHECK(std::find(g.begin(), g.end(), "G21") != g.end());

    SUBCASE("inches: G20 before the moves held until the unit is known; MMPM converted") {
        const auto h = apt_gcode("RAPID\nGOTO/1,2,3\nFEDRAT/MMPM,254\nGOTO/2,2,3\n");
        const auto at_g20 = std::find(h.begin(), h.end(), "G21");
        CHECK(at_g20 != h.end());  // MMPM: a metric program
        const auto i = apt_gcode("RAPID\nGOTO/1,2,3\nUNITS/INCHES\nFEDRAT/MMPM,254\nGOTO/2,2,3\n");
        const auto pos20 = std::find(i.begin(), i.end(), "G20") - i.begin();
        std::size_t first_move = 0;
        while (first_move < i.size() && i[first_move].rfind("G0", 0) != 0) ++first_move;
        CHECK(pos20 < std::ptrdiff_t(first_move));
        CHECK(moves_of(i)[1].at('F') == doctest::Approx(10));  // 254 mm/min = 10 in/min
    }
    SUBCASE("extrusion per mm on feed moves only, in the file's unit") {
        AptOptions o;
        o.extrusion_per_mm = 0.05;
        const auto e = moves_of(apt_gcode("UNITS/INCHES\nRAPID\nGOTO/0,0,1\nFEDRAT/IPM,10\nGOTO/3,4,1\n", o));
        CHECK(e[0].count('E') == 0);
        CHECK(e[1].at('E') == doctest::Approx(0.25));  // 5 in x 0.05: read as inches, 6.35 mm of filament for 127 mm
    }
    SUBCASE("LOAD/TOOL and MULTAX") {
        const auto l = apt_gcode("LOAD/TOOL,3\nMULTAX/OFF\nRAPID\nGOTO/1,1,1\n");
        CHECK(std::find(l.begin(), l.end(), "; LOAD/TOOL,3") != l.end());
        CHECK(moves_of(l)[0].at('K') == 1);
    }
}

TEST_CASE("CL CIRCLE: the arc to the next GOTO, counterclockwise about its axis, chords within the tolerance") {
    AptOptions o;
    o.chord_tolerance = 0.005;
    for (const double k : {1.0, -1.0}) {
        const std::string circle = "CIRCLE/0,0,0,0,0," + std::to_string(k) + ",10,0.001,0.5,1,0\n";
        const auto mv = moves_of(apt_gcode("UNITS/MM\nRAPID\nGOTO/10,0,0\nFEDRAT/MMPM,100\n" + circle + "GOTO/0,10,2\n", o));
        const double sweep = k > 0 ? kPi / 2 : 3 * kPi / 2;  // about -Z the arc goes the long way round
        const int chords = int(std::ceil(sweep / (2 * std::acos(1 - 0.005 / 10))));
        REQUIRE(int(mv.size()) == 1 + chords);
        double prev = 0;
        for (std::size_t i = 1; i < mv.size(); ++i) {
            const double x = mv[i].at('X'), y = mv[i].at('Y');
            CHECK(std::hypot(x, y) == doctest::Approx(10).epsilon(1e-6));
            CHECK(mv[i].at('Z') == doctest::Approx(2.0 * double(i) / chords).epsilon(1e-5));  // helical
            double t = std::atan2(y, x) * k;
            if (t < prev - 1e-9) t += 2 * kPi;
            CHECK(t > prev);  // turning one way, monotonically
            prev = t;
        }
        CHECK(mv.back().at('X') == 0);
        CHECK(mv.back().at('Y') == 10);
    }
}

TEST_CASE("CL data refused with the record's line and column") {
    struct Case {
        const char* text;
        std::uint64_t line;
        std::uint32_t column;
        const char* cause;
    };
    const Case cases[] = {
        {"UNITS/MM\nSPINDL/ON\n", 2, 1, "SPINDL"},
        {"UNITS/MM\nRAPID\nGOTO/1,2\n", 3, 8, "x,y,z"},
        {"UNITS/MM\nRAPID\nGOTO/1,x2,3\n", 3, 8, "not a number"},
        {"UNITS/MM\nRAPID\nGOTO/1,2,3e10\n", 3, 10, "1e9"},
        {"UNITS/MM\nRAPID\nGOTO/1,2,3,0,0,0\n", 3, 12, "length 0"},
        {"UNITS/MM\nGOTO/1,2,3\n", 2, 1, "before any FEDRAT"},
        {"UNITS/MM\nFEDRAT/IPR,0.1\n", 2, 8, "per revolution"},
        {"UNITS/FEET\n", 1, 7, "INCHES or MM"},
        {"UNITS/MM\nUNITS/INCHES\n", 2, 7, "change"},
        {"MULTAX/OFF\nRAPID\nGOTO/1,1,1,0,0,1\n", 3, 12, "MULTAX/OFF"},
        {"LOAD/TOOL,1.5\n", 1, 11, "whole number"},
        {"END-OF-PATH\n", 1, 1, "without a TOOL PATH"},
        {"TOOL PATH/A\nTOOL PATH/B\n", 2, 1, "inside a TOOL PATH"},
        {"TOOL PATH/A\nRAPID\nGOTO/1,1,1\n", 3, 1, "no END-OF-PATH"},
        {"UNITS/MM\nRAPID\nGOTO/10,0,0\nFEDRAT/MMPM,100\nCIRCLE/0,0,0,0,0,1,10\nFEDRAT/MMPM,50\n", 6, 1, "followed by the GOTO"},
        {"UNITS/MM\nRAPID\nGOTO/10,0,0\nFEDRAT/MMPM,100\nCIRCLE/0,0,0,0,0,1,10\nGOTO/0,12,0\n", 6, 1, "radius"},
        // A record the machine cannot reach: the translator's cause, at the record.
        {"UNITS/MM\nRAPID\nGOTO/10,0,50,0,0,-1\n", 3, 1, "the record as G-code"},
    };
    for (const Case& c : cases) {
        CAPTURE(c.text);
        const InputError e = error_of("xyzac-trt", c.text, FrontOptions{InputFormat::Apt});
        CHECK(e.file() == "t.cls");
        CHECK(e.line() == c.line);
        CHECK(e.column() == c.column);
        CHECK_MESSAGE(contains(e.message(), c.cause), e.what());
    }
}

TEST_CASE("input format by content: CL data is detected, G-code stays G-code") {
    CHECK(looks_like_apt("TOOL PATH/NORM_PART,TOOL,BALL_MILL_1.00"));
    CHECK(looks_like_apt("  $$ comment"));
    CHECK(looks_like_apt("GOTO/1,2,3"));
    CHECK_FALSE(looks_like_apt("G1 X1 Y2"));
    CHECK_FALSE(looks_like_apt("; generated by PrusaSlicer"));
    // A G-code file is translated as before when detected.
    const std::string g = "G28\nG1 X10 Y10 Z10 F600\nG1 X20\n";
    CHECK(translate_text("xyzac-trt", g, FrontOptions{}) == translate_text("xyzac-trt", g, FrontOptions{InputFormat::GCode}));
}

TEST_CASE("waypoint table: every point's tip and normalised vector by FK; E per mm of path") {
    // A conical helix whose vectors lean outward, of lengths 0.5 to 3, written as the research
    // tools write them (blanks, some commas, a comment, a blank line starting a second path).
    std::ostringstream t;
    std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> pts;
    t << "# x y z nx ny nz\n";
    for (int i = 0; i < 200; ++i) {
        if (i == 120) t << "\n";
        const double a = i * 0.1, r = 20 + 0.05 * i;
        const Eigen::Vector3d p(r * std::cos(a), r * std::sin(a), 5 + 0.02 * i);
        const Eigen::Vector3d n = (Eigen::Vector3d(0.4 * std::cos(a), 0.4 * std::sin(a), 1.0)) * (0.5 + 2.5 * (i % 7) / 6.0);
        pts.push_back({p, n.normalized()});
        char buf[200];
        std::snprintf(buf, sizeof buf, i % 3 ? "%.5f %.5f %.5f %.6f %.6f %.6f\n" : "%.5f, %.5f, %.5f, %.6f, %.6f, %.6f\n", p.x(), p.y(), p.z(), n.x(),
                      n.y(), n.z());
        t << buf;
    }
    Machine m = machine("xyzac-trt");
    const Kinematics k(m);
    FrontOptions fo{InputFormat::Waypoints};
    fo.extrusion_per_mm = 0.04;
    const std::string out = translate_text("xyzac-trt", t.str(), fo, "w.txt");
    // Whole output: the last joints of the output for each point, by splitting per point.
    m.motion.segment = false;
    const Kinematics k1(m);
    TranslatorOptions o;
    Translator tr(k1, o);
    InputFront front(tr, fo);
    std::string one;
    std::istringstream in(t.str());
    std::string line;
    std::uint64_t n = 0;
    while (std::getline(in, line)) front.feed(line, ++n, one);
    front.finish(n, one);
    const auto ends = move_ends(m, one);
    REQUIRE(ends.size() == pts.size());
    double worst_tip = 0, worst_axis = 0;
    for (std::size_t i = 0; i < pts.size(); ++i) {
        const Pose p = k1.forward(ends[i]);
        worst_tip = std::max(worst_tip, (p.tip - pts[i].first).norm());
        worst_axis = std::max(worst_axis, std::acos(std::clamp(p.axis.dot(pts[i].second), -1.0, 1.0)) * 180 / kPi);
    }
    CHECK(worst_tip < 1e-3);
    CHECK(worst_axis < 5e-3);
    // E: 0.04 per mm of printed path; the travel to the first point and across the blank line none.
    double path = 0, e = 0;
    for (std::size_t i = 1; i < pts.size(); ++i)
        if (i != 120) path += (pts[i].first - pts[i - 1].first).norm();
    for (const auto& l : lines_of(out))
        if (l.rfind("G1 ", 0) == 0 || l.rfind("G0 ", 0) == 0)
            if (const auto w = words_of(l); w.count('E')) e += w.at('E');
    CHECK(e == doctest::Approx(0.04 * path).epsilon(1e-4));
    MESSAGE("waypoints: worst tip error " << worst_tip << " mm, axis " << worst_axis << " deg");

    SUBCASE("refusals name the line and column") {
        const InputError a = error_of("xyzac-trt", "1 2 3 0 0 1\n1 2 3 0 0\n", fo);
        CHECK(a.line() == 2);
        CHECK(contains(a.message(), "6 numbers"));
        const InputError b = error_of("xyzac-trt", "1 2 3 0 0 1\n1 2 zz 0 0 1\n", fo);
        CHECK(b.line() == 2);
        CHECK(b.column() == 5);
        const InputError c = error_of("xyzac-trt", "1 2 3 0 0 0\n", fo);
        CHECK(contains(c.message(), "length 0"));
        const InputError d = error_of("xyzac-trt", "1 2 3 0 0 1 7\n", fo);
        CHECK(d.column() == 13);
    }
}

namespace {

struct CliResult {
    int code = -1;
    std::string out, err;
};

CliResult run_cli(const TempDir& dir, const std::string& args, const std::string& stdin_text) {
    const auto in = dir.write(".in", stdin_text);
    const auto out = dir.path / ".out", err = dir.path / ".err";
    const std::string cmd = quote(XLATE5_BINARY) + " " + args + " <" + quote(in.string()) + " >" + quote(out.string()) + " 2>" + quote(err.string());
    const int status = std::system(cmd.c_str());
    REQUIRE(WIFEXITED(status));
    return {WEXITSTATUS(status), read(out), read(err)};
}

}  // namespace

TEST_CASE("command line: --input-format, --extrusion-per-mm, --keep-out") {
    TempDir dir;
    const auto w = run_cli(dir, "--machine xyzac-trt --input-format waypoints --extrusion-per-mm 0.05", "0 0 5 0 0 1\n10 0 5 0 0.1 1\n");
    CHECK(w.code == 0);
    CHECK(contains(w.out, " E0.5"));
    const auto cl = run_cli(dir, "--machine xyzac-trt", "UNITS/MM\nRAPID\nGOTO/1,2,3\n");
    CHECK(cl.code == 0);
    const auto bad = run_cli(dir, "--machine xyzac-trt", "UNITS/MM\nSPINDL/ON\n");
    CHECK(bad.code == 1);
    CHECK(contains(bad.err, "<stdin>:2:1: CL record 'SPINDL'"));
    CHECK(run_cli(dir, "--machine xyzac-trt --input-format gcode --extrusion-per-mm 0.1", "G1 X1\n").code == 2);
    const auto g = run_cli(dir, "--machine xyzac-trt --extrusion-per-mm 0.1", "G1 X1 Y1 Z1\n");
    CHECK(g.code == 1);
    CHECK(contains(g.err, "<stdin>:1:1:"));
    const auto items = dir.write("items.csv", "100, 100, 0\n");
    CHECK(run_cli(dir, "--machine rw2 --keep-out " + quote(items.string()), "G1 X1\n").code == 3);
    const auto tube = run_cli(dir, "--machine addin4 --keep-out " + quote(items.string()), read(std::string(XLATE5_MACHINE_DIR_FOR_TESTS) + "/../examples/addin4_tube.gcode"));
    CHECK(tube.code == 0);
    CHECK(contains(tube.out, " A"));
    const auto broken = dir.write("broken.csv", "100, 100\n");
    const auto b = run_cli(dir, "--machine addin4 --keep-out " + quote(broken.string()), "G1 X1\n");
    CHECK(b.code == 1);
    CHECK(contains(b.err, "broken.csv:1:"));
}

TEST_CASE("messages that quote CL, waypoint and keep-out input write control bytes as \\xHH, never raw") {
    TempDir dir;
    auto raw_control = [](const std::string& s) {
        for (char c : s)
            if ((static_cast<unsigned char>(c) < 0x20 && c != '\n' && c != '\t') || c == 0x7F) return true;
        return false;
    };
    const std::string esc = "\x1b]0;owned\x07\x1b[2J";
    const std::string nul(1, '\0');
    // CL: an unknown record and a field that is not a number, each carrying ESC sequences.
    const auto cl = run_cli(dir, "--machine xyzac-trt", "UNITS/MM\n" + esc + "SPINDL/ON\n");
    CHECK(cl.code == 1);
    CHECK_FALSE(raw_control(cl.err));
    CHECK(contains(cl.err, "\\x1b]0;OWNED\\x07\\x1b[2JSPINDL"));  // (the record word, upper-cased)
    const auto num = run_cli(dir, "--machine xyzac-trt --input-format apt", "UNITS/MM\nRAPID\nGOTO/1,2" + nul + "x,3\n");
    CHECK(num.code == 1);
    CHECK_FALSE(raw_control(num.err));
    CHECK(contains(num.err, "'2\\x00x' is not a number"));
    // Waypoints.
    const auto w = run_cli(dir, "--machine xyzac-trt --input-format waypoints", "0 0 5 0 0 1\n1 2 " + esc + " 0 0 1\n");
    CHECK(w.code == 1);
    CHECK_FALSE(raw_control(w.err));
    CHECK(contains(w.err, "\\x1b"));
    // Keep-out items.
    const auto items = dir.write("items.csv", "100, 1" + nul + esc + ", 0\n");
    const auto k = run_cli(dir, "--machine addin4 --keep-out " + quote(items.string()), "G1 X1\n");
    CHECK(k.code == 1);
    CHECK_FALSE(raw_control(k.err));
    CHECK(contains(k.err, "\\x00\\x1b"));
}

TEST_CASE("NX CLSF as listed to a file: the information listing header is read, the tool path translates as without it" *
          doctest::skip(corpus_absent())) {
    // NX writes "Information listing" files with a rule, four lines (creator, date, work part,
    // node) and a rule before the CL records; auto-detection and the reader must take them.
    const std::string cls = read(corpus("nx_cldata/APT_Variable_Axis.cls"));
    const std::string header = "============================================================\n"
                               "Information listing created by :  jsmith\n"
                               "Date                           :  Tue Mar 12 10:15:02 2024\n"
                               "Current work part              :  C:\\parts\\bracket.prt\n"
                               "Node name                      :  cam-ws04\n"
                               "============================================================\n\n";
    const std::string plain = translate_text("xyzac-trt", cls, FrontOptions{});
    const std::string listed = translate_text("xyzac-trt", header + cls, FrontOptions{});
    // The four header lines are written as comments; nothing else differs.
    std::string without;
    int comments = 0;
    for (const auto& l : lines_of(listed)) {
        if (l.rfind("; Information listing", 0) == 0 || l.rfind("; Date", 0) == 0 || l.rfind("; Current work part", 0) == 0 ||
            l.rfind("; Node name", 0) == 0) {
            ++comments;
            continue;
        }
        without += l + "\n";
    }
    CHECK(comments == 4);
    CHECK(without == plain);
    // A header line after the first record is no header: refused where it is.
    const InputError e = error_of("xyzac-trt", "UNITS/MM\nNode name : x\n", FrontOptions{InputFormat::Apt});
    CHECK(e.line() == 2);
}

TEST_CASE("CL CIRCLE with TIMES,n: a helix of n turns about its axis to the GOTO, its height shared evenly") {
    // NX CLSF: CIRCLE/x,y,z,i,j,k,r,tol,ratio,diameter,corner,TIMES,n. From (10,0,7) down to
    // (10,0,0) about +Z, radius 10, 7 turns: 7 * 2 pi of sweep, 1 mm of height a turn.
    AptOptions o;
    o.chord_tolerance = 0.01;
    const auto mv = moves_of(apt_gcode("UNITS/MM\nRAPID\nGOTO/10,0,7\nFEDRAT/MMPM,100\n"
                                       "CIRCLE/0.000000,0.000000,0.000000,0.0000000,0.0000000,1.0000000,10.000000,0.002000,0.500000,6.000000,0.000000,TIMES,7\n"
                                       "GOTO/10,0,0\n", o));
    const int chords = int(std::ceil(7 * 2 * kPi / (2 * std::acos(1 - 0.01 / 10))));
    REQUIRE(int(mv.size()) == 1 + chords);
    double unwrapped = 0, prev_angle = 0;
    for (std::size_t i = 1; i < mv.size(); ++i) {
        const double x = mv[i].at('X'), y = mv[i].at('Y'), z = mv[i].at('Z');
        CHECK(std::hypot(x, y) == doctest::Approx(10).epsilon(1e-6));
        double a = std::atan2(y, x), d = a - prev_angle;
        if (d < 0) d += 2 * kPi;  // counterclockwise about +Z, less than a turn a chord
        unwrapped += d;
        prev_angle = a;
        // Height falls linearly with the angle turned: 1 mm a turn.
        CHECK(z == doctest::Approx(7 - unwrapped / (2 * kPi)).epsilon(1e-5));
    }
    CHECK(unwrapped == doctest::Approx(14 * kPi).epsilon(1e-9));
    CHECK(mv.back().at('Z') == 0);
    // TIMES needs a whole number of turns, at the CIRCLE's end.
    for (const char* bad : {"TIMES,0", "TIMES,2.5", "TIMES", "TIMES,2,1"}) {
        CAPTURE(bad);
        const InputError e = error_of("xyzac-trt", std::string("UNITS/MM\nRAPID\nGOTO/10,0,7\nFEDRAT/MMPM,100\nCIRCLE/0,0,0,0,0,1,10,0.002,0.5,6,0,") + bad + "\n",
                                      FrontOptions{InputFormat::Apt});
        CHECK(e.line() == 5);
        CHECK(contains(e.message(), "TIMES"));
    }
}

TEST_CASE("CL E with --extrusion-per-mm: written at the firmware's decimals, its total the path's, in inches as in millimetres" *
          doctest::skip(corpus_absent())) {
    // The total is computed here from the file's GOTOs (feed moves only: not the one after
    // RAPID), in mm, times E per mm; the output's relative E must add up to it within half a unit
    // of the last decimal written, and no E may have more decimals than the dialect's.
    const double epm = 0.0333;
    auto exact_total = [&](const std::string& text, double unit) {
        std::istringstream in(text);
        std::string line;
        bool rapid = false, known = false;
        Eigen::Vector3d prev = Eigen::Vector3d::Zero();
        double total = 0;
        while (std::getline(in, line)) {
            if (line.rfind("RAPID", 0) == 0) rapid = true;
            if (line.rfind("GOTO/", 0) != 0) continue;
            std::vector<double> v;
            std::stringstream s(line.substr(5));
            std::string f;
            while (std::getline(s, f, ',')) v.push_back(std::stod(f));
            const Eigen::Vector3d p(v[0] * unit, v[1] * unit, v[2] * unit);
            if (known && !rapid) total += (p - prev).norm() * epm;
            prev = p;
            known = true;
            rapid = false;
        }
        return total;
    };
    const Machine m = machine("xyzac-trt");
    const int ed = m.dialect.extrusion_decimals;
    auto check = [&](const std::string& text, double unit) {
        FrontOptions fo;
        fo.extrusion_per_mm = epm;
        fo.extrusion_decimals = ed;
        const std::string out = translate_text("xyzac-trt", text, fo);
        double total = 0;
        int es = 0;
        const std::regex e_word(" E(-?[0-9]+)(\\.([0-9]*))?");
        for (const auto& l : lines_of(out)) {
            std::smatch mt;
            if (!std::regex_search(l, mt, e_word)) continue;
            CAPTURE(l);
            CHECK(mt[3].str().size() <= std::size_t(ed));
            total += std::stod(mt[0].str().substr(2));
            ++es;
        }
        CHECK(es > 300);
        const double exact = exact_total(text, unit);
        CAPTURE(exact);
        CAPTURE(total);
        CHECK(std::abs(total - exact) <= 0.5 * std::pow(10.0, -ed) + 1e-9);
    };
    const std::string inches = read(corpus("nx_cldata/APT_Variable_Axis.cls"));  // FEDRAT/IPM: inches
    check(inches, 25.4);
    // The same path in millimetres (UNITS/MM, each coordinate times 25.4).
    std::istringstream in(inches);
    std::string line, mm = "UNITS/MM\n";
    while (std::getline(in, line)) {
        if (line.rfind("GOTO/", 0) == 0) {
            std::stringstream s(line.substr(5));
            std::string f, g = "GOTO/";
            for (int i = 0; std::getline(s, f, ','); ++i) {
                char b[40];
                std::snprintf(b, sizeof b, "%.6f", i < 3 ? std::stod(f) * 25.4 : std::stod(f));
                if (i) g += ',';
                g += b;
            }
            line = g;
        } else if (line.rfind("FEDRAT/IPM,", 0) == 0) {
            line = "FEDRAT/MMPM," + std::to_string(std::stod(line.substr(11)) * 25.4);
        }
        mm += line + "\n";
    }
    check(mm, 1.0);
}

TEST_CASE("a UTF-8 byte-order mark opens G-code, CL data and keep-out items; a keep-out header row is skipped") {
    const std::string bom = "\xEF\xBB\xBF";
    const std::string g = "G28\nG1 X10 Y10 Z10 F600\nG1 X20\n";
    CHECK(translate_text("xyzac-trt", bom + g, FrontOptions{}) == translate_text("xyzac-trt", g, FrontOptions{}));
    const std::string cl = "UNITS/MM\nRAPID\nGOTO/1,2,3\n";
    CHECK(translate_text("xyzac-trt", bom + cl, FrontOptions{}) == translate_text("xyzac-trt", cl, FrontOptions{}));
    const auto plain = parse_keep_out("10, 20, 0\n30 40 5\n", "i.csv");
    for (const std::string& text : {bom + "10, 20, 0\n30 40 5\n", std::string("x,y,height\n10, 20, 0\n30 40 5\n"),
                                   bom + "\"X\";\"Y\";\"Height (mm)\"\r\n10, 20, 0\n30 40 5\n"}) {
        CAPTURE(text);
        const auto items = parse_keep_out(text, "i.csv");
        REQUIRE(items.items.size() == plain.items.size());
        for (std::size_t i = 0; i < items.items.size(); ++i) {
            CHECK(items.items[i].height == plain.items[i].height);
            CHECK((items.items[i].centre - plain.items[i].centre).norm() == 0);
        }
    }
    // Names after the first item, or numbers like inf, are no header: refused where they are.
    CHECK_THROWS_AS(parse_keep_out("10, 20, 0\nx,y,height\n", "i.csv"), InputError);
    CHECK_THROWS_AS(parse_keep_out("inf, nan, inf\n", "i.csv"), InputError);
}
