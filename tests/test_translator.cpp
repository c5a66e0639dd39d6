// SPDX-License-Identifier: GPL-3.0-or-later
// Translator: modal G-code semantics, passthrough, G92/G28, G43.4/G43.5/G49, errors, inverse.
// Joint values are checked against the sources' formulas written out here (Andersons, Twente 2023, eq. 4.5 for
// rw2, Grutle (Oslo 2015) pseudo code 4.1 for pentarod), never against the program's own output.
#include <doctest/doctest.h>

#include "helpers.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <map>
#include <memory>
#include <sstream>
#include <utility>
#include <string>
#include <vector>

#include "translators/error.hpp"
#include "translators/kinematics/kinematics.hpp"
#include "translators/machine/machine.hpp"
#include "translators/pipeline/translator.hpp"

using namespace xlate5;
using namespace xlate5::test;

namespace {


// Half a unit of the third decimal (the output precision) plus floating-point slack.
constexpr double kPrinted = 5e-4 + 1e-9;

Machine load(const std::string& name, bool segment = true) {
    Machine m = load_machine(std::string(XLATE5_MACHINE_DIR_FOR_TESTS) + "/" + name + ".toml");
    m.motion.segment = segment;
    return m;
}

// These tests look at what one input move becomes; splitting moves to the tolerance is the
// motion stage's business and is tested in test_motion.cpp, so here it is off.
constexpr bool kOneLinePerMove = false;

// A machine, its kinematics and a translator, built in place (the translator keeps references).
struct Rig {
    Machine machine;
    Kinematics kin;
    Translator tr;
    std::string out;

    explicit Rig(const std::string& name, TranslatorOptions options = {}, bool segment = kOneLinePerMove)
        : machine(load(name, segment)), kin(machine), tr(kin, std::move(options)) {}

    int j(char letter) const {
        const int i = machine.joint_index(letter);
        REQUIRE(i >= 0);
        return i;
    }
    double q(char letter) const { return tr.joints()[std::size_t(j(letter))]; }

    // Feeds one line and returns only the text it produced.
    std::string feed(const std::string& line, std::uint64_t line_no = 1) {
        const std::size_t start = out.size();
        tr.feed(line, line_no, out);
        return out.substr(start);
    }
};



// The only line of `text`, as words.
std::map<char, double> one_line(const std::string& text) {
    const auto lines = lines_of(text);
    REQUIRE_MESSAGE(lines.size() == 1, "expected one line, got '" << text << "'");
    return words_of(lines[0]);
}

bool has_line(const std::string& text, const std::string& wanted) {
    for (const auto& l : lines_of(text))
        if (l == wanted) return true;
    return false;
}

// Andersons (Twente 2023) eq. 4.5 as printed (angles in degrees): machine joints X Y Z for tip (X', Y', Z').
struct Rw2Joints {
    double x, y, z;
};
Rw2Joints eq45(const Eigen::Vector3d& tip, double a, double b, double la = 26.5, double lb = 47.9) {
    const double A = rad(a), B = rad(b);
    return {tip.x() + std::sin(A) * la + std::cos(A) * std::sin(B) * lb,
            tip.y() - la + std::cos(A) * la - std::sin(A) * std::sin(B) * lb,
            tip.z() + std::cos(B) * lb - lb};
}
// Eq. 4.5 solved for the tip.
Eigen::Vector3d eq45_tip(double x, double y, double z, double a, double b, double la = 26.5, double lb = 47.9) {
    const double A = rad(a), B = rad(b);
    return {x - std::sin(A) * la - std::cos(A) * std::sin(B) * lb, y + la - std::cos(A) * la + std::sin(A) * std::sin(B) * lb,
            z - std::cos(B) * lb + lb};
}

// rw2's joints equal eq. 4.5 at `tip`, with the given A and B.
void check_rw2_joints(const Rig& r, const Eigen::Vector3d& tip, double a, double b) {
    const Rw2Joints e = eq45(tip, a, b);
    CHECK(std::abs(r.q('X') - e.x) < 1e-9);
    CHECK(std::abs(r.q('Y') - e.y) < 1e-9);
    CHECK(std::abs(r.q('Z') - e.z) < 1e-9);
    CHECK(std::abs(r.q('A') - a) < 1e-9);
    CHECK(std::abs(r.q('B') - b) < 1e-9);
}

bool near(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double tol) { return (a - b).norm() <= tol; }

// Runs `line` expecting an InputError; returns it.
InputError expect_error(Rig& r, const std::string& line, std::uint64_t line_no = 1) {
    try {
        r.tr.feed(line, line_no, r.out);
    } catch (const InputError& e) {
        return e;
    }
    FAIL("expected an InputError for '" << line << "'");
    return InputError("", 0, 0, "");
}


std::string fmt9(double v) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.9f", v);
    return buf;
}

// rw2 with the tip placed at (100, 100, 10), A = 0, B = 0.
void place_rw2(Rig& r) {
    r.feed("G1 X100 Y100 Z10 A0 B0 F1200");
    REQUIRE(near(r.tr.pose().tip, {100, 100, 10}, 1e-9));
    check_rw2_joints(r, {100, 100, 10}, 0, 0);
}

}  // namespace

// ---- modal state ------------------------------------------------------------------------

TEST_CASE("translator: a rotary-only move keeps the tip and moves X Y Z per eq. 4.5") {
    Rig r("rw2");
    place_rw2(r);
    const Eigen::Vector3d tip = r.tr.pose().tip;

    const std::string o = r.feed("G1 A30");
    CHECK(near(r.tr.pose().tip, tip, 1e-9));
    check_rw2_joints(r, tip, 30, 0);

    const auto w = one_line(o);
    const Rw2Joints e = eq45(tip, 30, 0);
    CHECK(w.at('G') == 1);
    REQUIRE(w.count('X'));
    REQUIRE(w.count('Y'));
    CHECK(std::abs(w.at('X') - e.x) <= kPrinted);
    CHECK(std::abs(w.at('Y') - e.y) <= kPrinted);
    CHECK(w.at('A') == 30);
    CHECK(w.count('Z') == 0);  // B = 0: Z' = Z, unchanged
    CHECK(w.count('B') == 0);
    // A pure turn runs at the machine's rotary feed (3600 deg/min): 30 degrees take 1/120 min,
    // and Marlin divides the XYZ length of the move by F (its rule when XYZ moves).
    const Rw2Joints before = eq45(tip, 0, 0);
    const double dxy = std::hypot(w.at('X') - before.x, w.at('Y') - before.y);
    CHECK(w.at('F') == doctest::Approx(dxy / (30.0 / 3600.0)).epsilon(1e-3));

    // B too: now Z moves as well.
    const auto w2 = one_line(r.feed("G1 B20"));
    check_rw2_joints(r, tip, 30, 20);
    const Rw2Joints e2 = eq45(tip, 30, 20);
    CHECK(std::abs(w2.at('X') - e2.x) <= kPrinted);
    CHECK(std::abs(w2.at('Y') - e2.y) <= kPrinted);
    CHECK(std::abs(w2.at('Z') - e2.z) <= kPrinted);
    CHECK(w2.at('B') == 20);
    CHECK(w2.count('A') == 0);
}

TEST_CASE("translator: a tip move keeps the modal rotary angles") {
    Rig r("rw2");
    place_rw2(r);
    r.feed("G1 A30");
    const auto w = one_line(r.feed("G1 X10"));
    check_rw2_joints(r, {10, 100, 10}, 30, 0);
    CHECK(r.q('A') == 30);
    CHECK(w.count('A') == 0);
    CHECK(std::abs(w.at('X') - eq45({10, 100, 10}, 30, 0).x) <= kPrinted);
    CHECK(near(r.tr.pose().tip, {10, 100, 10}, 1e-9));
}

TEST_CASE("translator: tool axis of rw2 follows the file's stated convention") {
    // rw2.toml: u = (sin B cos A, -sin B sin A, cos B).
    Rig r("rw2");
    place_rw2(r);
    r.feed("G1 A35 B-25");
    const double A = rad(35), B = rad(-25);
    CHECK(near(r.tr.pose().axis, {std::sin(B) * std::cos(A), -std::sin(B) * std::sin(A), std::cos(B)}, 1e-12));
}

TEST_CASE("translator: F is written only when the input gives it; G0 and G1 are kept") {
    Rig r("rw2");
    place_rw2(r);
    auto w = one_line(r.feed("G1 X101 F600"));
    CHECK(w.at('F') == 600);
    w = one_line(r.feed("G1 X102"));
    CHECK(w.count('F') == 0);
    w = one_line(r.feed("G1 X103 E0.5"));
    CHECK(w.count('F') == 0);
    CHECK(w.at('E') == 0.5);
    w = one_line(r.feed("G0 X104 F9000"));
    CHECK(w.at('G') == 0);
    CHECK(w.at('F') == 9000);
    w = one_line(r.feed("G1 Y101"));
    CHECK(w.at('G') == 1);
}

TEST_CASE("translator: G91 makes tip and rotary words relative; joints stay absolute") {
    Rig r("rw2");
    place_rw2(r);
    const std::string o = r.feed("G91");
    CHECK(o == "G90\nM83\n");  // joint targets are always absolute; E follows G91 (Marlin 2)
    CHECK_FALSE(r.tr.modes().absolute);
    CHECK(r.tr.modes().e_relative);

    auto w = one_line(r.feed("G1 X1"));
    CHECK(std::abs(w.at('X') - 101) <= kPrinted);
    w = one_line(r.feed("G1 X1"));
    CHECK(std::abs(w.at('X') - 102) <= kPrinted);
    CHECK(near(r.tr.pose().tip, {102, 100, 10}, 1e-9));
    check_rw2_joints(r, {102, 100, 10}, 0, 0);

    r.feed("G1 A10");
    r.feed("G1 A10");
    check_rw2_joints(r, {102, 100, 10}, 20, 0);

    CHECK(r.feed("G90") == "G90\nM82\n");
    CHECK(r.tr.modes().absolute);
    r.feed("G1 X50");
    check_rw2_joints(r, {50, 100, 10}, 20, 0);
}

TEST_CASE("translator: G20 inches are converted to millimetres; G20 and G21 emit G21") {
    Rig r("rw2");
    place_rw2(r);
    CHECK(r.feed("G20") == "G21\n");
    CHECK(r.tr.modes().inches);
    const auto w = one_line(r.feed("G1 X1 Y2 Z0.5 F10 E0.1"));
    CHECK(near(r.tr.pose().tip, {25.4, 50.8, 12.7}, 1e-9));
    check_rw2_joints(r, {25.4, 50.8, 12.7}, 0, 0);
    CHECK(std::abs(w.at('F') - 254) < 1e-9);
    CHECK(std::abs(w.at('E') - 2.54) < 1e-9);
    // Rotary words stay degrees.
    r.feed("G1 A10");
    CHECK(r.q('A') == 10);
    CHECK(r.feed("G21") == "G21\n");
    CHECK_FALSE(r.tr.modes().inches);
    r.feed("G1 X1");
    CHECK(near(r.tr.pose().tip, {1, 50.8, 12.7}, 1e-9));
}

TEST_CASE("translator: E mode follows the latest of G90/G91/M82/M83 (Marlin 2)") {
    Rig r("rw2");
    CHECK(r.feed("M83") == "M83\n");
    CHECK(r.tr.modes().e_relative);
    CHECK(r.feed("G90") == "G90\nM82\n");
    CHECK_FALSE(r.tr.modes().e_relative);
    CHECK(r.feed("M83") == "M83\n");
    CHECK(r.tr.modes().e_relative);
    CHECK(r.tr.modes().absolute);  // M83 touches E only
    CHECK(r.feed("M82") == "M82\n");
    CHECK_FALSE(r.tr.modes().e_relative);
    CHECK(r.feed("G91") == "G90\nM83\n");
    CHECK(r.tr.modes().e_relative);
    CHECK(r.feed("M82") == "M82\n");
    CHECK_FALSE(r.tr.modes().e_relative);
    CHECK_FALSE(r.tr.modes().absolute);  // still G91 for the axes
}

TEST_CASE("translator: axis words without a command continue the modal G0/G1") {
    Rig r("rw2");
    place_rw2(r);
    r.feed("G1 X1");
    auto w = one_line(r.feed("X2"));
    CHECK(w.at('G') == 1);
    CHECK(std::abs(w.at('X') - 2) <= kPrinted);
    check_rw2_joints(r, {2, 100, 10}, 0, 0);
    r.feed("G0 X3");
    w = one_line(r.feed("Y90 Z11"));
    CHECK(w.at('G') == 0);
    check_rw2_joints(r, {3, 90, 11}, 0, 0);
}

TEST_CASE("translator: axis words before any G0/G1 are an error") {
    Rig r("rw2");
    const InputError e = expect_error(r, "X1 Y2", 4);
    CHECK(e.line() == 4);
    CHECK(e.column() == 1);
    CHECK(contains(e.message(), "motion"));
    CHECK(r.out.empty());
    // A mode-only line does not start a motion either.
    Rig r2("rw2");
    r2.feed("G90");
    expect_error(r2, "X1");
}

// ---- passthrough ------------------------------------------------------------------------

TEST_CASE("translator: lines it does not need pass through unchanged and in order") {
    Rig r("rw2");
    const std::vector<std::string> in = {"M104 S200", "T1", ";comment", "G4 P100", "M117 Hello world", "M106 S255 ; fan",
                                         "(setup)", "", "M140 S60"};
    for (std::size_t i = 0; i < in.size(); ++i) r.feed(in[i], i + 1);
    CHECK(lines_of(r.out) == in);
}

TEST_CASE("translator: CRLF input gives LF output without the carriage return") {
    Rig r("rw2");
    CHECK(r.feed("M104 S200\r") == "M104 S200\n");
    CHECK(r.feed(";note\r") == ";note\n");
    CHECK(r.feed("\r") == "\n");
    CHECK(r.feed("N12 M105*38") == "M105\n");  // host line number and checksum are not passed on
    CHECK(r.feed("%") == "%\n");
    place_rw2(r);
    const auto w = one_line(r.feed("G1 X101\r"));
    CHECK(std::abs(w.at('X') - 101) <= kPrinted);
}

TEST_CASE("translator: M104/M109 with a T tool parameter pass through") {
    // Multi-extruder slicer output: T here is M104's tool index, not a tool change.
    Rig r("rw2");
    // T after M104/M109/M221 names a tool, it is not a second command (this once failed as
    // "two commands on this line take words").
    for (const std::string line : {"M104 T1 S200", "M109 S210 T0", "M221 T0 S95"}) {
        CAPTURE(line);
        std::string o;
        CHECK_NOTHROW(o = r.feed(line));
        CHECK(o == line + "\n");
    }
}

TEST_CASE("translator: a CNC preamble splits into one command per line and consumes G49") {
    Rig r("rw2");
    const std::string o = r.feed("G21 G40 G49 G80 G90 M5 T1 M6 G54 G94");
    const auto lines = lines_of(o);
    for (const auto& l : lines) {
        CAPTURE(l);
        // One command per line, no other words.
        const auto w = words_of(l);
        CHECK(w.size() == 1);
    }
    for (const std::string wanted : {"G21", "G40", "G80", "G90", "M82", "M5", "T1", "M6", "G54"}) {
        CAPTURE(wanted);
        CHECK(has_line(o, wanted));
    }
    CHECK_FALSE(has_line(o, "G49"));
    CHECK_FALSE(contains(o, "G43"));
    CHECK(r.tr.mode() == OrientationMode::Joints);  // G49: tool-centre-point control off
    // The output must not depend on the order of modal words within one line (RS274 executes a
    // line in a fixed order): G94 (feed per minute, the firmware's only feed mode) is consumed
    // here just as it is in "G94 G49".
    CHECK_FALSE(has_line(o, "G94"));

    // The same preamble with G94 first.
    Rig r2("rw2");
    const std::string o2 = r2.feed("G21 G40 G94 G49 G80 G90 M5 T1 M6 G54");
    CHECK_FALSE(has_line(o2, "G94"));
    CHECK_FALSE(has_line(o2, "G49"));
}

TEST_CASE("translator: under G43.4 G93/G94 are understood, not sent; G93 moves need F") {
    Rig r("rw2");
    const std::string o = r.feed("G21 G40 G80 G90 G94");
    CHECK_FALSE(has_line(o, "G94"));
    CHECK(has_line(o, "G21"));
    CHECK(has_line(o, "G90"));
    CHECK(r.tr.mode() == OrientationMode::Angles);
    r.feed("G1 A0 B0 F600");
    CHECK(r.feed("G93") == "");
    CHECK(r.tr.modes().inverse_time);
    const InputError e = expect_error(r, "G1 X10 Y10 Z1");
    CHECK(contains(e.message(), "G93"));
    // 1/F minutes for 10 mm: F = 0.5 means 2 minutes, so 5 mm/min.
    const auto w = one_line(r.feed("G1 X10 Y10 Z1 A0 B0 F0.5"));
    (void)w;
    r.feed("G1 X20 F0.5");
    const auto w2 = words_of(lines_of(r.out).back());
    CHECK(w2.at('F') == doctest::Approx(5.0));
    CHECK(r.feed("G94") == "");
    CHECK_FALSE(r.tr.modes().inverse_time);
}

TEST_CASE("translator: under G49 and G93 every joint move keeps its F, even when it repeats") {
    // LinuxCNC and RepRapFirmware read F as 1/minutes per move under G93: a move without F is
    // an error there, so the feed that the same value had on the line before must be written again.
    Rig r("rw2");
    r.feed("G49");
    CHECK(has_line(r.feed("G93"), "G93"));
    CHECK(one_line(r.feed("G1 X1 F10")).at('F') == 10);
    CHECK(one_line(r.feed("G1 X2 F10")).at('F') == 10);
    CHECK(has_line(r.feed("G94"), "G94"));
    r.feed("G1 X3 F600");
    CHECK(one_line(r.feed("G1 X4 F600")).count('F') == 0);  // per minute: modal, written once
}

// ---- G92 ----------------------------------------------------------------------------------

TEST_CASE("translator: G92 E0 passes through") {
    Rig r("rw2");
    place_rw2(r);
    CHECK(r.feed("G92 E0") == "G92 E0\n");
    check_rw2_joints(r, {100, 100, 10}, 0, 0);
}

TEST_CASE("translator: G92 A under G43.4 is sent and changes the joint") {
    Rig r("rw2");
    place_rw2(r);
    const auto before = r.tr.joints();
    CHECK(r.feed("G92 A-168") == "G92 A-168\n");
    CHECK(r.q('A') == -168);
    // The machine did not move: the other joints are unchanged.
    CHECK(r.q('X') == before[std::size_t(r.j('X'))]);
    CHECK(r.q('Y') == before[std::size_t(r.j('Y'))]);
    CHECK(r.q('Z') == before[std::size_t(r.j('Z'))]);
    CHECK(r.q('B') == before[std::size_t(r.j('B'))]);
    // Its tip is where eq. 4.5 puts it with the declared A.
    CHECK(near(r.tr.pose().tip, eq45_tip(r.q('X'), r.q('Y'), r.q('Z'), -168, 0), 1e-9));
}

TEST_CASE("translator: G92 X Y Z under G43.4 shifts the program frame and is not sent") {
    Rig r("rw2");
    place_rw2(r);
    r.feed("G1 A20 B10");
    const Eigen::Vector3d tip = r.tr.pose().tip;
    const auto joints = r.tr.joints();
    CHECK(r.feed("G92 X0 Y0 Z0") == "");
    CHECK(r.tr.joints() == joints);
    CHECK(near(r.tr.pose().tip, tip, 1e-12));
    CHECK(near(r.tr.program_offset(), tip, 1e-12));

    r.feed("G1 X1");
    CHECK(near(r.tr.pose().tip, tip + Eigen::Vector3d(1, 0, 0), 1e-9));
    check_rw2_joints(r, tip + Eigen::Vector3d(1, 0, 0), 20, 10);

    r.feed("G1 X-2 Y3 Z0.5");
    check_rw2_joints(r, tip + Eigen::Vector3d(-2, 3, 0.5), 20, 10);

    // G92 E together with X: E is sent, X is not.
    const auto w = one_line(r.feed("G92 X0 E0"));
    CHECK(w.at('G') == 92);
    CHECK(w.at('E') == 0);
    CHECK(w.count('X') == 0);
}

// ---- G28 ----------------------------------------------------------------------------------

TEST_CASE("translator: G28 resets the joints to home and the next move writes every joint") {
    Rig r("rw2");
    place_rw2(r);
    r.feed("G1 X120 A40 B-15");
    CHECK(r.feed("G28") == "G28\n");
    CHECK(r.q('X') == 0);
    CHECK(r.q('Y') == 0);
    CHECK(r.q('Z') == 300);   // rw2: Z homes at its max switch (Andersons, Twente 2023, sec. 3.5)
    CHECK(r.q('A') == -168);  // rw2: A homes at its min switch
    CHECK(r.q('B') == 0);
    CHECK(r.tr.program_offset().isZero());

    // A = -168 and B = 0 equal the home values but are commanded, so they must be written: the
    // firmware's state after homing is not what xlate5 last told it.
    const Eigen::Vector3d tip(50, 50, 5);
    const auto w = one_line(r.feed("G1 X50 Y50 Z5 A-168 B0"));
    for (char c : {'X', 'Y', 'Z', 'A', 'B'}) {
        CAPTURE(c);
        CHECK(w.count(c) == 1);
    }
    check_rw2_joints(r, tip, -168, 0);
    const Rw2Joints e = eq45(tip, -168, 0);
    CHECK(std::abs(w.at('X') - e.x) <= kPrinted);
    CHECK(std::abs(w.at('Y') - e.y) <= kPrinted);
    CHECK(std::abs(w.at('Z') - e.z) <= kPrinted);
}

TEST_CASE("translator: G28 with axis flags homes only those joints") {
    Rig r("rw2");
    place_rw2(r);
    r.feed("G1 A40 B-15");
    const auto before = r.tr.joints();
    CHECK(r.feed("G28 X") == "G28 X\n");
    CHECK(r.q('X') == 0);
    for (char c : {'Y', 'Z', 'A', 'B'}) {
        CAPTURE(c);
        CHECK(r.q(c) == before[std::size_t(r.j(c))]);
    }
    // "G28 X Y" homes X and Y only (the lexer once rejected it).
    std::string o;
    CHECK_NOTHROW(o = r.feed("G28 X Y"));
    CHECK(o == "G28 X Y\n");
    CHECK(r.q('Y') == 0);
    CHECK(r.q('A') == 40);
}

TEST_CASE("translator: Andersons (Twente 2023) start code G28, G92 A-168, G1 A0 B0 leaves X Y Z") {
    Rig r("rw2");
    CHECK(r.feed("G28") == "G28\n");
    CHECK(r.feed("G92 A-168") == "G92 A-168\n");
    const auto w = one_line(r.feed("G1 A0 B0"));
    CHECK(w.at('G') == 1);
    CHECK(w.at('A') == 0);
    CHECK(w.at('B') == 0);
    // Before the tip is placed, a rotary-only move turns the rotaries only: X Y Z neither
    // change nor are written.
    for (char c : {'X', 'Y', 'Z'}) {
        CAPTURE(c);
        CHECK(w.count(c) == 0);
        CHECK(r.q(c) == r.machine.joints[std::size_t(r.j(c))].home);
    }
    CHECK(r.q('Z') == 300);
    // The first tip move then follows eq. 4.5.
    r.feed("G1 X100 Y100 Z0.3 E1 F1200");
    check_rw2_joints(r, {100, 100, 0.3}, 0, 0);
}

// ---- G43.5 / G49 on pentarod -----------------------------------------------------------------

namespace {

Eigen::Matrix3d Rx(double deg) { return Eigen::AngleAxisd(rad(deg), Eigen::Vector3d::UnitX()).toRotationMatrix(); }
Eigen::Matrix3d Rz(double deg) { return Eigen::AngleAxisd(rad(deg), Eigen::Vector3d::UnitZ()).toRotationMatrix(); }

// Grutle (Oslo 2015): u = (sin A sin C, sin A cos C, cos A).
Eigen::Vector3d pentarod_u(double a, double c) {
    return {std::sin(rad(a)) * std::sin(rad(c)), std::sin(rad(a)) * std::cos(rad(c)), std::cos(rad(a))};
}

}  // namespace

TEST_CASE("translator: pentarod G43.5 solves pseudo code 4.1 for several tool vectors") {
    Rig r("pentarod");
    CHECK(r.tr.mode() == OrientationMode::Vector);

    auto w = one_line(r.feed("G1 X1 Y2 Z3 I0 J0 K1"));
    CHECK(std::abs(r.q('A')) < 1e-9);
    CHECK(std::abs(r.q('X') - 1) < 1e-9);
    CHECK(std::abs(r.q('Y') - 2) < 1e-9);
    CHECK(std::abs(r.q('Z') - 3) < 1e-9);
    CHECK(std::abs(w.at('X') - 1) <= kPrinted);

    struct Case {
        Eigen::Vector3d p, u;
    };
    const Case cases[] = {
        {{10, -5, 2}, {1, 1, 1}},
        {{-20, 15, 4}, {0, 0.5, 0.8660254}},
        {{5, 5, 0.2}, {0.3, -0.4, 0.866}},
        {{0, 30, 10}, {-1, 0, 1}},
        {{12.5, -7.25, 3}, {-0.2, -0.7, 0.3}},
        {{1, 2, 3}, {0, 0, 2}},  // not unit: only the direction counts
    };
    int line = 2;
    for (const Case& c : cases) {
        const std::string text = "G1 X" + fmt9(c.p.x()) + " Y" + fmt9(c.p.y()) + " Z" + fmt9(c.p.z()) + " I" + fmt9(c.u.x()) +
                                 " J" + fmt9(c.u.y()) + " K" + fmt9(c.u.z());
        CAPTURE(text);
        const std::string o = r.feed(text, std::uint64_t(line++));
        const double A = r.q('A'), C = r.q('C');
        const Eigen::Vector3d u = c.u.normalized();
        // FK of the joints gives back u.
        CHECK(near(pentarod_u(A, C), u, 1e-9));
        CHECK(near(r.tr.pose().axis, u, 1e-9));
        CHECK(near(r.tr.pose().tip, c.p, 1e-9));
        CHECK(A >= -90 - 1e-9);
        CHECK(A <= 90 + 1e-9);
        // Machine XYZ = R_x(A) R_z(C) p.
        const Eigen::Vector3d m = Rx(A) * Rz(C) * c.p;
        CHECK(std::abs(r.q('X') - m.x()) < 1e-9);
        CHECK(std::abs(r.q('Y') - m.y()) < 1e-9);
        CHECK(std::abs(r.q('Z') - m.z()) < 1e-9);
        // The printed words agree (3 decimals).
        w = one_line(o);
        if (w.count('X')) CHECK(std::abs(w.at('X') - m.x()) <= kPrinted);
        if (w.count('Y')) CHECK(std::abs(w.at('Y') - m.y()) <= kPrinted);
        if (w.count('Z')) CHECK(std::abs(w.at('Z') - m.z()) <= kPrinted);
        if (w.count('A')) CHECK(std::abs(w.at('A') - A) <= kPrinted);
        if (w.count('C')) CHECK(std::abs(w.at('C') - C) <= kPrinted);
    }
}

TEST_CASE("translator: pentarod G43.5 tool vector errors") {
    Rig r("pentarod");
    r.feed("G1 X1 Y2 Z3 I0 J0 K1");
    const std::string before = r.out;
    const auto joints = r.tr.joints();
    InputError e = expect_error(r, "G1 X2 I0 J0 K0", 5);
    CHECK(contains(e.message(), "length 0"));
    CHECK(e.line() == 5);
    CHECK(e.column() == 7);
    CHECK(r.out == before);
    CHECK(r.tr.joints() == joints);
    // Rotary words are not the orientation under G43.5.
    e = expect_error(r, "G1 X2 A10");
    CHECK(e.column() == 7);
    // Pointing down: A would need 180, outside -90..90.
    e = expect_error(r, "G1 I0 J0 K-1");
    CHECK(contains(e.message(), "limits"));
    CHECK(r.tr.joints() == joints);
}

TEST_CASE("translator: I J K under G43.4 are an error") {
    Rig r("rw2");
    place_rw2(r);
    InputError e = expect_error(r, "G1 X1 I0 J0 K1");
    CHECK(e.column() == 7);
    CHECK(contains(e.message(), "G43.5"));

    Rig p("pentarod");
    p.feed("G43.4");
    CHECK(p.tr.mode() == OrientationMode::Angles);
    e = expect_error(p, "G1 X1 I0 J0 K1");
    CHECK(e.column() == 7);
    // ...while its rotary letters now give the orientation.
    p.feed("G1 X1 Y2 Z3 A30 C45");
    CHECK(near(p.tr.pose().axis, pentarod_u(30, 45), 1e-12));
    const Eigen::Vector3d m = Rx(30) * Rz(45) * Eigen::Vector3d(1, 2, 3);
    CHECK(std::abs(p.q('X') - m.x()) < 1e-9);
    CHECK(std::abs(p.q('Y') - m.y()) < 1e-9);
    CHECK(std::abs(p.q('Z') - m.z()) < 1e-9);
}

TEST_CASE("translator: G49 on pentarod sends joint values as they are") {
    Rig r("pentarod");
    CHECK(r.feed("G49") == "");
    CHECK(r.tr.mode() == OrientationMode::Joints);
    const auto w = one_line(r.feed("G1 X5 A10"));
    CHECK(w.at('X') == 5);
    CHECK(w.at('A') == 10);
    CHECK(r.q('X') == 5);
    CHECK(r.q('A') == 10);
    CHECK(r.q('C') == 0);
    // FK: the table is tilted by A, so the tool axis in the part frame is u(A, C).
    CHECK(near(r.tr.pose().axis, pentarod_u(10, 0), 1e-12));
    CHECK(near(r.tr.pose().tip, Rz(0).transpose() * Rx(10).transpose() * Eigen::Vector3d(5, 0, 0), 1e-12));
    const auto w2 = one_line(r.feed("G1 Y-3 C370"));  // C is multi-turn: sent as given
    CHECK(w2.at('Y') == -3);
    CHECK(w2.at('C') == 370);
    CHECK(w2.count('X') == 0);
    // Under G49, I J K are not joint words.
    expect_error(r, "G1 I0 J0 K1");
    // And back to G43.5.
    r.feed("G43.5");
    r.feed("G1 X0 Y0 Z1 I0 J0 K1");
    CHECK(std::abs(r.q('A')) < 1e-9);
}

// ---- bad input --------------------------------------------------------------------------------

TEST_CASE("translator: errors name the input, line and column") {
    Rig r("rw2");
    const InputError e = expect_error(r, " G1 Xnan", 7);
    CHECK(std::string(e.what()).rfind("<stdin>:7:", 0) == 0);
    CHECK(e.line() == 7);
    CHECK(e.column() >= 5);
    CHECK(e.column() <= 6);
    CHECK(r.out.empty());

    TranslatorOptions o;
    o.input_name = "part.gcode";
    Rig named("rw2", o);
    const InputError e2 = expect_error(named, "G1 X1 X2", 123456789012ull);
    CHECK(std::string(e2.what()).rfind("part.gcode:123456789012:7: ", 0) == 0);
    CHECK(contains(e2.message(), "twice"));
}

TEST_CASE("translator: a command's code has at most one decimal (G43.4), read to the nearest tenth") {
    // RS274: G codes such as G43.4 and G61.1 carry one decimal; a value off a tenth (G1.25, or
    // G0.95 read as neither G0.9 nor G1) is not a code.
    for (const char* line : {"G1.25 X1", "G0.95", "M104.05 S200", "G90.15", "G-0.05"}) {
        CAPTURE(line);
        Rig r("rw2");
        const InputError e = expect_error(r, line);
        CHECK(contains(e.message(), "more than one decimal"));
        CHECK(e.column() == 1);
    }
    // Within 1e-6 of a tenth is that tenth: G90.0000001 is G90, G91.00000001 G91 (relative).
    Rig r("rw2");
    for (const char* line : {"G90.0000001", "G91.00000001", "G90.0", "M82.0000000001", "G-0.0"}) {
        CAPTURE(line);
        CHECK_NOTHROW(r.feed(line));
    }
}

TEST_CASE("translator: a failing line leaves output and state unchanged") {
    Rig r("rw2");
    place_rw2(r);
    r.feed("G1 A30 B10 E1");
    const std::string out = r.out;
    const auto joints = r.tr.joints();
    const Pose pose = r.tr.pose();
    const Eigen::Vector3d offset = r.tr.program_offset();
    const Modes modes = r.tr.modes();
    const OrientationMode mode = r.tr.mode();

    for (const char* bad : {"G91 G1 X1000",          // G91 would be written, then the move fails
                            "G20 G1 X1000",           // same with G20
                            "G49 G1 X5 A400",         // the mode switch must be undone too
                            "G1 X1 X2", "G1 A170 E2", "G1 Q5", "G2 X1 Y1 I1 J0", "G1 Xnan", "G1 X1 F0",
                            "G92 Q1", "G1 X(", "G28 Q",
                            "M5 G1 X1000",            // M5 would be written before the move fails
                            "X1 M1234", "G1 X1 M106 M8 P1"}) {
        CAPTURE(std::string(bad));
        expect_error(r, bad, 9);
        CHECK(r.out == out);
        CHECK(r.tr.joints() == joints);
        CHECK(near(r.tr.pose().tip, pose.tip, 0));
        CHECK(near(r.tr.pose().axis, pose.axis, 0));
        CHECK(r.tr.program_offset() == offset);
        CHECK(r.tr.modes().absolute == modes.absolute);
        CHECK(r.tr.modes().inches == modes.inches);
        CHECK(r.tr.modes().e_relative == modes.e_relative);
        CHECK(r.tr.modes().motion == modes.motion);
        CHECK(r.tr.mode() == mode);
    }
    // And the next good line is translated as if the bad ones were never there.
    r.feed("G1 X101");
    check_rw2_joints(r, {101, 100, 10}, 30, 10);
}

TEST_CASE("translator: G2/G3 under tool-centre-point control are linearised; bad arcs name the line") {
    Rig r("rw2");
    place_rw2(r);
    std::string o;
    CHECK_NOTHROW(o = r.feed("G2 X110 Y100 I5 J0", 3));
    CHECK(lines_of(o).size() > 10);  // a half circle of radius 5 in chords
    CHECK(near(r.tr.pose().tip, {110, 100, 10}, 1e-9));
    InputError e = expect_error(r, "G1 X1\nG3 X1", 3);  // the lexer rejects the embedded newline first
    e = expect_error(r, "  G3 X110 Y100 R5", 4);       // start = end: no arc by radius
    CHECK(contains(e.message(), "arc"));
    CHECK(e.column() == 3);
    CHECK(e.line() == 4);
}

TEST_CASE("translator: a word the machine does not have is an error") {
    Rig r("rw2");
    place_rw2(r);
    const InputError e = expect_error(r, "G1 Q5", 2);
    CHECK(e.column() == 4);
    CHECK(contains(e.message(), "Q"));
    const InputError e2 = expect_error(r, "G1 X1 C5", 2);  // rw2 has no C
    CHECK(e2.column() == 7);
    CHECK(contains(e2.message(), "C"));
}

TEST_CASE("translator: a move outside the joint limits is an error mentioning limits") {
    Rig r("rw2");
    place_rw2(r);
    // A printing move may not change solution (a travel move to A170 would end on another one).
    InputError e = expect_error(r, "G1 A170 E1", 6);
    CHECK(contains(e.message(), "limits"));
    CHECK(contains(e.message(), "A"));
    CHECK(e.line() == 6);
    e = expect_error(r, "G1 B-101");
    CHECK(contains(e.message(), "limits"));
    // The tip at X = 300 needs joint X > 250.
    e = expect_error(r, "G1 X300");
    CHECK(contains(e.message(), "limits"));
    // Exactly at the limit is allowed.
    r.feed("G1 A168");
    CHECK(r.q('A') == 168);
}

TEST_CASE("translator: a word given twice is an error at its second place") {
    Rig r("rw2");
    place_rw2(r);
    const InputError e = expect_error(r, "G1 X1 X2");
    CHECK(e.column() == 7);
    CHECK(contains(e.message(), "twice"));
    expect_error(r, "G1 A1 Y2 a3");
}

// ---- extruder letter ------------------------------------------------------------------------

TEST_CASE("translator: --extruder-letter A turns A into E on a B+C machine") {
    TranslatorOptions o;
    o.extruder_letter = 'A';
    o.start_mode = OrientationMode::Joints;  // koc5's files here are joint space
    Rig r("koc5", o);
    const auto w = one_line(r.feed("G1 X1 B2 C3 A0.5"));
    CHECK(w.at('E') == 0.5);
    CHECK(w.count('A') == 0);
    CHECK(w.at('X') == 1);
    CHECK(w.at('B') == 2);
    CHECK(w.at('C') == 3);
    CHECK(r.q('B') == 2);
    CHECK(r.q('C') == 3);
    // With A carrying extrusion, an E word is ambiguous.
    const InputError e = expect_error(r, "G1 X2 E1");
    CHECK(e.column() == 7);
    // G92 A0 resets the extruder.
    CHECK(r.feed("G92 A0") == "G92 E0\n");
}

// ---- inverse --------------------------------------------------------------------------------

TEST_CASE("translator: inverse rw2 turns the translated joints back into the tool-space input") {
    Rig fwd("rw2");
    TranslatorOptions o;
    o.inverse = true;
    Rig inv("rw2", o);

    struct Step {
        const char* line;
        Eigen::Vector3d tip;
        double a, b;
    };
    const Step steps[] = {
        {"G1 X100 Y100 Z10 A0 B0 F1200", {100, 100, 10}, 0, 0},
        {"G1 X110 Y95 Z10.2 A30 B15 E1.5", {110, 95, 10.2}, 30, 15},
        {"G1 A-45 B-20", {110, 95, 10.2}, -45, -20},
        {"G1 X90 Y120 Z12 A100 B45 E2.25", {90, 120, 12}, 100, 45},
        {"G0 X80", {80, 120, 12}, 100, 45},
    };
    // Last value written per letter by the inverse (the preview writes only what changed).
    std::map<char, double> shown;
    int n = 1;
    for (const Step& s : steps) {
        CAPTURE(std::string(s.line));
        const std::string joint_text = fwd.feed(s.line, std::uint64_t(n));
        check_rw2_joints(fwd, s.tip, s.a, s.b);
        const auto jw = one_line(joint_text);

        const std::string tool_text = inv.feed(lines_of(joint_text).at(0), std::uint64_t(n++));
        // The inverse saw the printed joints: its tip is eq. 4.5 inverted at those joints.
        for (const auto& [letter, value] : jw)
            if (letter != 'G' && letter != 'E' && letter != 'F') CHECK(std::abs(inv.q(letter) - value) < 1e-9);
        const Eigen::Vector3d expect_tip = eq45_tip(inv.q('X'), inv.q('Y'), inv.q('Z'), inv.q('A'), inv.q('B'));
        CHECK(near(inv.tr.pose().tip, expect_tip, 1e-9));
        // ... which is the original tip up to the 3-decimal rounding of the joints.
        CHECK(near(inv.tr.pose().tip, s.tip, 2e-3));
        CHECK(std::abs(inv.q('A') - s.a) <= kPrinted);
        CHECK(std::abs(inv.q('B') - s.b) <= kPrinted);

        const auto tw = one_line(tool_text);
        CHECK(tw.at('G') == jw.at('G'));
        for (const auto& [letter, value] : tw) shown[letter] = value;
        CHECK(std::abs(shown.at('X') - s.tip.x()) <= 2e-3);
        CHECK(std::abs(shown.at('Y') - s.tip.y()) <= 2e-3);
        CHECK(std::abs(shown.at('Z') - s.tip.z()) <= 2e-3);
        CHECK(std::abs(shown.at('A') - s.a) <= kPrinted);
        CHECK(std::abs(shown.at('B') - s.b) <= kPrinted);
        if (jw.count('E')) CHECK(tw.at('E') == jw.at('E'));
        if (jw.count('F')) CHECK(tw.at('F') == jw.at('F'));
    }

    // The inverse output, translated forward again, gives the same joints.
    Rig fwd2("rw2");
    for (const auto& l : lines_of(inv.out)) fwd2.feed(l);
    for (char c : {'X', 'Y', 'Z', 'A', 'B'}) {
        CAPTURE(c);
        CHECK(std::abs(fwd2.q(c) - inv.q(c)) < 1e-3);
    }
}

TEST_CASE("translator: inverse passes G92 and G28 in tool-space letters") {
    TranslatorOptions o;
    o.inverse = true;
    Rig inv("rw2", o);
    CHECK(inv.feed("G28") == "G28\n");
    CHECK(inv.feed("G92 A-168") == "G92 A-168\n");
    CHECK(inv.q('A') == -168);
    CHECK(inv.feed("G92 E0") == "G92 E0\n");
    CHECK(inv.feed("M104 S200") == "M104 S200\n");
    // Joint-space input has no G43.4/G43.5: its words are joints, which is what G49 says, so G49
    // changes nothing and writes nothing (in the tool-space output it would switch to joints).
    expect_error(inv, "G43.4");
    expect_error(inv, "G43.5");
    const std::vector<double> before = inv.tr.joints();
    CHECK(inv.feed("G49") == "");
    const std::string preamble = inv.feed("G21 G40 G49 G80 G90");  // the S3-DeformFDM ring's (Zhang et al., SIGGRAPH Asia 2022)
    CHECK(!contains(preamble, "G49"));
    CHECK(contains(preamble, "G40\n"));
    CHECK(contains(preamble, "G80\n"));
    CHECK(inv.tr.joints() == before);
    CHECK(inv.tr.mode() == OrientationMode::Joints);
    CHECK(!inv.feed("G1 X100 Y100 Z10 A30 B10 F1200").empty());
    CHECK(inv.q('A') == 30);
}

TEST_CASE("translator: inverse in G43.5 writes the tool vector whole, so translating it again gives the first translation") {
    // rw2's axis u = (sin B cos A, -sin B sin A, cos B): from B0.01 to B0 at A0 only I changes
    // in its 7 written decimals (K stays 1.0000000), which a lone I would lose (I0 alone reads
    // as the vector 0 0 0).
    const char* lines[] = {"G1 X100 Y100 Z10 A0 B0.01 F1200", "G1 X101 Y100 Z10 A0 B0 E0.1",    "G1 X102 Y101 Z10 A30 B15 E0.1",
                           "G1 X103 Y102 Z10 A30 B15.001 E0.1", "G1 X104 Y102 Z10 A0 B0.02 E0.1", "G1 X105 Y102 Z10 A0 B0.01 E0.1",
                           "G0 X105 Y102 Z12 A-40 B20",          "G1 X104 Y103 Z12 A-40.0004 B20 E0.1"};
    Rig fwd("rw2", {}, true);
    TranslatorOptions o;
    o.inverse = true;
    o.preview_form = OrientationMode::Vector;
    Rig inv("rw2", o);
    TranslatorOptions again;
    again.start_mode = OrientationMode::Vector;
    Rig fwd2("rw2", again, true);
    const Machine& m = fwd.machine;
    std::uint64_t n = 0;
    for (const char* line : lines) {
        CAPTURE(std::string(line));
        ++n;
        const std::string joints = fwd.feed(line, n);
        std::string tool;
        for (const auto& l : lines_of(joints)) tool += inv.feed(l, n);
        for (const auto& l : lines_of(tool)) {
            CAPTURE(l);
            const auto w = words_of(l);
            CHECK(w.count('I') == w.count('J'));  // all of I J K, or none
            CHECK(w.count('J') == w.count('K'));
            fwd2.feed(l, n);
        }
        // The second translation ends where the first did: the same tip and tool axis (through
        // FK of the joints each wrote), within the machine's tolerances.
        const Pose first = fwd.kin.forward(fwd.tr.joints()), second = fwd2.kin.forward(fwd2.tr.joints());
        CHECK((first.tip - second.tip).norm() <= m.motion.tolerance);
        CHECK(std::acos(std::clamp(first.axis.dot(second.axis), -1.0, 1.0)) * 180 / kPi <= m.motion.angle_tolerance);
    }
    // Off the pole the joints themselves agree to their written decimals.
    for (char c : {'X', 'Y', 'Z', 'A', 'B'}) {
        CAPTURE(c);
        CHECK(std::abs(fwd2.q(c) - fwd.q(c)) <= 2e-3);
    }
}

TEST_CASE("translator: the compact-words option reads the input as its declaration line does, in both directions") {
    const std::string body[] = {"G49", "G1X100Y100Z10A30B10F1200", "G1X101.5E-05"};
    for (const bool inverse : {false, true}) {
        CAPTURE(inverse);
        TranslatorOptions declared_options, flagged_options;
        declared_options.inverse = flagged_options.inverse = inverse;
        flagged_options.compact_words = true;
        Rig declared("rw2", declared_options), flagged("rw2", flagged_options), plain("rw2", declared_options);
        declared.feed("; xlate5: compact-words");
        std::uint64_t n = 1;
        for (const std::string& line : body) {
            CAPTURE(line);
            ++n;
            CHECK(flagged.feed(line, n) == declared.feed(line, n));
        }
        // X101.5 and a 5 mm retract, not X0.001015.
        CHECK(flagged.q('X') == doctest::Approx(101.5));
        // Without either, the last line is refused as ambiguous.
        plain.feed(body[0]);
        plain.feed(body[1]);
        CHECK_THROWS_AS(plain.feed(body[2]), InputError);
    }
}

TEST_CASE("translator: G43.4 H1 and G43.5 H1 switch the mode; the H register is not used") {
    Rig r("pentarod");
    CHECK(r.feed("G49") == "");
    CHECK(r.feed("G43.4 H1") == "");
    CHECK(r.tr.mode() == OrientationMode::Angles);
    CHECK(r.feed("G43.5 H2") == "");
    CHECK(r.tr.mode() == OrientationMode::Vector);
    // H anywhere else is still an unknown word on a move.
    CHECK_THROWS_AS(r.feed("G1 X1 H1"), InputError);
}

TEST_CASE("translator: the words of one line mean the same in any order (RS274 order)") {
    for (const std::string line : {"G90 G21 G49", "G49 G21 G90", "G21 G49 G90"}) {
        Rig r("rw2");
        CAPTURE(line);
        CHECK(r.feed(line) == "G21\nG90\nM82\n");
        CHECK(r.tr.mode() == OrientationMode::Joints);
    }
}

// ---- the bundled examples ------------------------------------------------------------------

TEST_CASE("bundled examples: until the first extrusion the tip crosses the bed only above the clearance (FK of the output)") {
    // The firmware moves each joint linearly from where G28 leaves it (the machine file's home):
    // the tip may come down to the bed, or rise from it, only straight up and down.
    constexpr double kClearance = 2.0;  // mm above the plate
    constexpr double kStill = 1e-4;     // mm across per 1/100 of a move: straight down, but for the printed digits
    const std::string examples = std::string(XLATE5_MACHINE_DIR_FOR_TESTS) + "/../examples/";
    for (const auto& [file, name] : {std::pair<const char*, const char*>{"rw2_flared_wall.gcode", "rw2"}, {"pentarod_dome.gcode", "pentarod"}}) {
        const std::string example = file;
        CAPTURE(example);
        Rig r(name, {}, true);  // split to the tolerance, as shipped
        r.tr.set_lookback(Translator::kDefaultLookback);
        std::istringstream in(read(examples + file));
        REQUIRE(in.str().size() > 1000);
        std::string line;
        std::uint64_t n = 0;
        while (std::getline(in, line)) r.tr.feed(line, ++n, r.out);
        r.tr.finish(r.out);

        const Machine& m = r.machine;
        std::vector<double> q = m.home_joints();
        bool printed = false;
        int travels = 0;
        double lowest_crossing = 1e9;
        for (std::string l : lines_of(r.out)) {
            if (const auto c = l.find(';'); c != std::string::npos) l.resize(c);
            while (!l.empty() && l.back() == ' ') l.pop_back();
            if (l.empty() || l[0] != 'G') continue;
            const auto w = words_of(l);
            const double g = w.at('G');
            if (g == 28) {
                q = m.home_joints();
                continue;
            }
            if (g != 0 && g != 1 && g != 92) continue;
            std::vector<double> next = q;
            for (std::size_t j = 0; j < m.joints.size(); ++j)
                if (w.count(m.joints[j].output)) next[j] = w.at(m.joints[j].output);
            if (g == 92) {  // the firmware is told where it is: no motion
                q = next;
                continue;
            }
            if (w.count('E') && w.at('E') > 0) {
                printed = true;
                break;
            }
            ++travels;
            Eigen::Vector3d before = r.kin.forward(q).tip;
            for (int s = 1; s <= 100; ++s) {
                std::vector<double> at(q.size());
                for (std::size_t j = 0; j < q.size(); ++j) at[j] = q[j] + (next[j] - q[j]) * s / 100.0;
                const Eigen::Vector3d tip = r.kin.forward(at).tip;
                const double across = std::hypot(tip.x() - before.x(), tip.y() - before.y());
                if (across > kStill) lowest_crossing = std::min(lowest_crossing, std::min(tip.z(), before.z()));
                INFO("output '" << l << "': tip (" << tip.x() << ", " << tip.y() << ", " << tip.z() << ")");
                CHECK(tip.z() >= -1e-6);                                     // never into the bed
                if (tip.z() < kClearance || before.z() < kClearance) CHECK(across <= kStill);  // low: only vertically
                before = tip;
            }
            q = next;
        }
        MESSAGE(example << ": " << travels << " joint moves before the first extrusion, lowest crossing at z " << lowest_crossing);
        CHECK(printed);
        CHECK(travels >= 2);
        CHECK(lowest_crossing >= kClearance);
    }
}

// ---- no move leaves untranslated ------------------------------------------------------------

namespace {

// The joints a G0/G1 output line commands, the others kept from `q`.
std::vector<double> joints_of(const Machine& m, const std::map<char, double>& w, std::vector<double> q) {
    for (std::size_t j = 0; j < m.joints.size(); ++j)
        if (w.count(m.joints[j].output)) q[j] = w.at(m.joints[j].output);
    return q;
}

bool is_move_line(const std::string& l) {
    return l.rfind("G0 ", 0) == 0 || l.rfind("G1 ", 0) == 0;
}

}  // namespace

TEST_CASE("translator: a move line carrying M, S or T codes is translated; the codes go on their own lines in RS274 order") {
    struct Codes {
        const char* words;
        std::vector<std::string> before, after;  // the code lines before and after the move
    };
    const std::vector<Codes> codes = {
        {"M08", {"M8"}, {}},
        {"M106", {"M106"}, {}},
        {"M106 S128", {"M106 S128"}, {}},
        {"S600 M03", {"M3 S600"}, {}},
        {"M3 S600", {"M3 S600"}, {}},
        {"S600", {"S600"}, {}},
        {"T1", {"T1"}, {}},
        {"M6 T1", {"T1", "M6"}, {}},
        {"M9 M5", {"M5", "M9"}, {}},
        {"M8 M3 S600", {"M3 S600", "M8"}, {}},
        {"M104 S200 T0", {"M104 S200 T0"}, {}},
        {"M30", {}, {"M30"}},
        {"M2 M9", {"M9"}, {"M2"}},
        {"M0", {}, {"M0"}},
    };
    struct Form {
        const char* prefix;
        int gcode;  // the move's G (the modal one is G1)
        std::vector<std::string> modal;  // lines the prefix writes
    };
    const std::vector<Form> forms = {{"", 1, {}}, {"G0 ", 0, {}}, {"G1 ", 1, {}}, {"G54 ", 1, {"G54"}}, {"G54 G0 ", 0, {"G54"}}};
    struct Case {
        const char* machine;
        const char* start;   // places the tip, ends in modal G1
        const char* rotary;  // the move's rotary words
        char letters[2];
        double angles[2];    // their values
        Eigen::Vector3d tip;
    };
    const std::vector<Case> cases = {
        {"xyzac-trt", "G43.4 G0 X0 Y0 Z10 A0 C0", "A-30 C60", {'A', 'C'}, {-30, 60}, {1, 2, 10}},
        {"rw2", "G43.4 G0 X100 Y100 Z10 A0 B0", "A-5 B10", {'A', 'B'}, {-5, 10}, {1, 2, 10}},
        {"koc5", "G43.4 G0 X0 Y0 Z10 B0 C0", "B20 C-45", {'B', 'C'}, {20, -45}, {1, 2, 10}},
    };
    for (const Case& c : cases)
        for (const Form& f : forms)
            for (const Codes& k : codes) {
                Rig r(c.machine);
                r.feed(c.start);
                r.feed("G1 X0 F600");
                const std::string line = std::string(f.prefix) + "X1 Y2 Z10 " + c.rotary + " " + k.words;
                CAPTURE(c.machine);
                CAPTURE(line);
                const std::vector<double> q_before = r.tr.joints();
                const std::string o = r.feed(line, 7);
                const auto lines = lines_of(o);
                std::size_t moves = 0, first_move = lines.size();
                std::vector<std::string> before, after;
                for (std::size_t i = 0; i < lines.size(); ++i) {
                    if (is_move_line(lines[i])) {
                        ++moves;
                        first_move = std::min(first_move, i);
                        const auto w = words_of(lines[i]);
                        CHECK(w.at('G') == f.gcode);
                        CHECK(w.count('S') == 0);
                        CHECK(w.count('T') == 0);
                        CHECK(w.count('M') == 0);
                        // FK of the joints as written: the programmed tip and angles.
                        const auto q = joints_of(r.machine, w, q_before);
                        CHECK(near(r.kin.forward(q).tip, c.tip, 0.005));
                        for (int n = 0; n < 2; ++n) CHECK(std::abs(q[std::size_t(r.j(c.letters[n]))] - c.angles[n]) <= kPrinted);
                    } else {
                        (moves == 0 ? before : after).push_back(lines[i]);
                    }
                }
                CHECK(moves == 1);
                // Codes in RS274's order: M/S/T first, then the modal G codes, the move, the stops.
                std::vector<std::string> want = k.before;
                want.insert(want.end(), f.modal.begin(), f.modal.end());
                CHECK(before == want);
                CHECK(after == k.after);
                // The next move starts from where the firmware really is.
                const std::string next = r.feed("G1 X5 F100");
                const auto w = words_of(lines_of(next).back());
                CHECK(near(r.kin.forward(joints_of(r.machine, w, r.tr.joints())).tip, {5, 2, 10}, 0.005));
                CHECK(near(r.tr.pose().tip, {5, 2, 10}, 1e-9));
            }
}

TEST_CASE("translator: a code that does not say what the axis words of its line are is refused at the word") {
    Rig r("rw2");
    place_rw2(r);
    // An unknown M code with axis words: a move or the code's parameters? Neither is guessed.
    InputError e = expect_error(r, "X1 Y2 M1234", 9);
    CHECK(e.line() == 9);
    CHECK(e.column() == 1);
    CHECK(contains(e.message(), "M1234"));
    // Two M codes, one word that only an M code takes.
    e = expect_error(r, "G1 X1 M106 M8 P1", 10);
    CHECK(e.column() == 15);
    CHECK(r.out.find("M1234") == std::string::npos);
    // Firmware settings that take axis letters pass as written.
    CHECK(r.feed("M92 X80 Y80 Z400") == "M92 X80 Y80 Z400\n");
    CHECK(r.feed("M203 A100 B100") == "M203 A100 B100\n");
    // Lines of codes alone pass as written, as before.
    CHECK(r.feed("M106 S255 ; fan") == "M106 S255 ; fan\n");
    CHECK(r.feed("M3 M8 S600") == "M3 S600\nM8\n");
}

TEST_CASE("translator: legal RS274 is not refused: G0 under G93 needs no F; a lone S passes under G43.4 and G43.5") {
    // G93 gives the duration of feed moves; a rapid has none (RS274/NGC 3.5.19, LinuxCNC).
    for (const char* name : {"rw2", "xyzac-trt"}) {
        Rig r(name);
        CAPTURE(name);
        r.feed("G1 X1 Y2 Z10 F600");
        r.feed("G93");
        std::string o;
        REQUIRE_NOTHROW(o = r.feed("G0 X20 Y10 Z12"));
        CHECK(near(r.tr.pose().tip, {20, 10, 12}, 1e-9));
        const auto w = words_of(lines_of(o).back());
        CHECK(near(r.kin.forward(joints_of(r.machine, w, r.tr.joints())).tip, {20, 10, 12}, 0.005));
        // A feed move still needs its F.
        CHECK(contains(expect_error(r, "G1 X21").message(), "G93"));
    }
    for (const char* mode : {"G43.4", "G43.5"}) {
        Rig r("koc5");
        r.feed(mode);
        CHECK(r.feed("S600") == "S600\n");
        CHECK(r.feed("S0 ; laser off") == "S0 ; laser off\n");
    }
}

TEST_CASE("translator: inverse splits a joint move that carries M codes too, and its joints go through FK") {
    TranslatorOptions o;
    o.inverse = true;
    Rig inv("rw2", o);
    inv.feed("G1 X100 Y100 Z10 A0 B0 F1200");
    const std::string out = inv.feed("X90 Y95 Z12 A-5 B10 M106 S128");
    const auto lines = lines_of(out);
    REQUIRE(lines.size() == 2);
    CHECK(lines[0] == "M106 S128");
    // The preview's tip is FK of the joints (eq. 4.5 solved for the tip), not the joint values.
    const auto w = words_of(lines[1]);
    const Eigen::Vector3d tip = eq45_tip(90, 95, 12, -5, 10);
    CHECK(std::abs(w.at('X') - tip.x()) <= kPrinted);
    CHECK(std::abs(w.at('Y') - tip.y()) <= kPrinted);
    CHECK(std::abs(w.at('Z') - tip.z()) <= kPrinted);
}

TEST_CASE("translator: a rotary word's checks keep their order: not a rotary, inside a tilted plane, under G43.5") {
    Rig p("pentarod");
    p.feed("G1 X1 Y2 Z3 I0 J0 K1");
    InputError e = expect_error(p, "G1 X2 Q5");  // no joint Q: not a tool-space word, whatever the mode
    CHECK(e.column() == 7);
    CHECK(contains(e.message(), "not a tool-space word"));
    e = expect_error(p, "G1 X2 A10");
    CHECK(e.column() == 7);
    CHECK(contains(e.message(), "under G43.5"));
    p.feed("G68.2 J30");
    e = expect_error(p, "G1 X2 A10");  // inside the plane its check comes first
    CHECK(e.column() == 7);
    CHECK(contains(e.message(), "ambiguous"));
    e = expect_error(p, "G1 X2 Q5");
    CHECK(contains(e.message(), "not a tool-space word"));

    Rig r("rw2");
    place_rw2(r);
    r.feed("G1 X1 A10 B5");  // allowed: G43.4, no plane
    CHECK(std::abs(r.q('A') - 10) < 1e-12);
    CHECK(std::abs(r.q('B') - 5) < 1e-12);
    e = expect_error(r, "G1 X1 A10 C5");
    CHECK(e.column() == 11);
    CHECK(contains(e.message(), "not a tool-space word"));
}

TEST_CASE("a coolant or spindle-stop code on a line with G53 or G43 goes on its own line; the words stay with the G code") {
    // LinuxCNC's ending `G53 G49 Z30 M09`: M09 takes no words, so Z30 is G53's (machine
    // coordinates, sent as a joint value under G49); M09 runs first (RS274's order).
    const Machine m = load_machine(std::string(XLATE5_MACHINE_DIR_FOR_TESTS) + "/xyzac-trt.toml");
    const Kinematics k(m);
    auto run = [&](const std::string& text) {
        TranslatorOptions o;
        o.input_name = "t.ngc";
        Translator t(k, o);
        std::string out;
        std::uint64_t n = 0;
        for (const auto& l : lines_of(text)) t.feed(l, ++n, out);
        t.finish(out);
        return out;
    };
    const std::string out = run("G90\nG53 G49 Z30 M09\n");
    CHECK(contains(out, "M9\nG53 Z30\n"));
    // Under tool-centre-point control, the move with G43 is refused at the word, saying why and what to do.
    try {
        run("G90\nG43 H1 Z5 M08\n");
        FAIL("no error");
    } catch (const InputError& e) {
        CHECK(e.line() == 2);
        CHECK(e.column() == 8);
        CHECK(contains(e.message(), "word Z on a line with G43 (tool length compensation)"));
        CHECK(contains(e.message(), "put the move on a line of its own"));
    }
    // Two commands that both take words: the message names the word and both.
    try {
        run("G90\nG49\nG53 G10 L2 P1 X0\n");
        FAIL("no error");
    } catch (const InputError& e) {
        CHECK(contains(e.message(), "could belong to"));
        CHECK(contains(e.message(), "G53"));
        CHECK(contains(e.message(), "G10"));
    }
}

TEST_CASE("a feed under 0.05 mm/min is never written F0 (Marlin ignores F0 and keeps the last feed)") {
    const Machine m = load_machine(std::string(XLATE5_MACHINE_DIR_FOR_TESTS) + "/xyzac-trt.toml");
    const Kinematics k(m);
    TranslatorOptions o;
    Translator t(k, o);
    std::string out;
    std::uint64_t n = 0;
    for (const char* l : {"G1 X1 Y0 Z5 F1200", "G1 X2 F0.04", "G1 X3 F0.0123", "G1 X4 F0.05", "G1 X5 F1e-12"}) {
        if (std::string(l).find('e') != std::string::npos) break;  // (G-code has no exponent)
        t.feed(l, ++n, out);
    }
    t.feed("G1 X5 F0.0000000001", ++n, out);
    t.finish(out);
    CAPTURE(out);
    std::vector<double> feeds;
    for (const auto& l : lines_of(out)) {
        const auto f = l.find(" F");
        if (f == std::string::npos) continue;
        CHECK(l.substr(f + 2) != "0");
        feeds.push_back(std::stod(l.substr(f + 2)));
    }
    REQUIRE(feeds.size() == 5);
    CHECK(feeds[0] == 1200);
    CHECK(feeds[1] == doctest::Approx(0.04).epsilon(0.05));   // two significant digits
    CHECK(feeds[2] == doctest::Approx(0.0123).epsilon(0.05));
    CHECK(feeds[3] == doctest::Approx(0.1));                  // 0.05 at one decimal, as before
    CHECK(feeds[4] == 1e-9);                                  // the least nine decimals write
}

TEST_CASE("a refused line is undone by a quiet replay: collisions already told are not told again") {
    // rw2 with its test bodies, --collision warn: the head tilted onto a wall printed earlier
    // collides (tests/test_collide.cpp). A printing line refused after it (past X's travel) is
    // undone by running the lines since the stages' copy again, quietly: the collisions told,
    // the output and the beads are those of the program without it, with the look-back or not.
    const Machine m = load_with_bodies("rw2");
    const Kinematics k(m);
    const std::string program = rw2_wall() + "G1 X38 Y100 Z20 B60\nG1 Z6.2\nG1 X38 Y110 E0.5\n";
    for (const std::size_t lookback : {std::size_t(0), Translator::kDefaultLookback}) {
        CAPTURE(lookback);
        auto run = [&](bool refused, std::string& out, std::size_t& beads) {
            std::vector<std::string> told;
            TranslatorOptions o;
            o.collision = CollisionPolicy::Warn;
            o.on_collision = [&told](const CollisionEvent& e) { told.push_back(e.message() + " #" + std::to_string(e.moves_written)); };
            Translator t(k, o);
            t.set_lookback(lookback);
            std::uint64_t n = 0;
            for (const auto& line : lines_of(program)) t.feed(line, ++n, out);
            if (refused) {
                CHECK_THROWS_AS(t.feed("G1 X38 Y111 E0.5 X-1000", ++n, out), InputError);  // two X: the interpreter's
                CHECK_THROWS_AS(t.feed("G1 X1000 Y111 E0.5", ++n, out), InputError);      // past X's travel: the planner's
            }
            t.feed("G1 X38 Y112 E0.5", ++n, out);
            t.finish(out);
            beads = t.collision()->beads();
            return told;
        };
        std::string out_with, out_without;
        std::size_t beads_with = 0, beads_without = 0;
        const auto with = run(true, out_with, beads_with), without = run(false, out_without, beads_without);
        CHECK(!without.empty());
        CHECK(with == without);
        CHECK(beads_with == beads_without);
        // Without the look-back the firmware's position after a refused line is not known: the
        // next line names every joint.
        if (lookback > 0) CHECK(out_with == out_without);
    }
}
