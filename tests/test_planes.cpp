// SPDX-License-Identifier: GPL-3.0-or-later
// Tilted work planes (G68.2 / G53.1 / G69), the join of planar files along build directions, and
// the post-processing guards (provenance header, binary G-code, in place). Every pose is checked
// by forward kinematics of the joints written, against the plane computed here from the
// definition (Fanuc's G68.2, LinuxCNC 2.9's remap: R = Rz(I) Rx(J) Rz(K), origin + R p), not
// from the translator's own state.
#include <doctest/doctest.h>

#include <cmath>
#include <sstream>
#include <sys/wait.h>

#include "helpers.hpp"
#include "translators/error.hpp"
#include "translators/kinematics/kinematics.hpp"
#include "translators/machine/machine.hpp"
#include "translators/pipeline/translator.hpp"
#include "translators/pipeline/work_plane.hpp"

using namespace xlate5;
using namespace xlate5::test;
namespace fs = std::filesystem;

namespace {

Machine machine(const std::string& name) { return load_machine(std::string(XLATE5_MACHINE_DIR_FOR_TESTS) + "/" + name + ".toml"); }

// Rotations written out element by element (right-handed, angles in degrees).
Eigen::Matrix3d rot_x(double deg) {
    const double c = std::cos(rad(deg)), s = std::sin(rad(deg));
    Eigen::Matrix3d r;
    r << 1, 0, 0, 0, c, -s, 0, s, c;
    return r;
}
Eigen::Matrix3d rot_z(double deg) {
    const double c = std::cos(rad(deg)), s = std::sin(rad(deg));
    Eigen::Matrix3d r;
    r << c, -s, 0, s, c, 0, 0, 0, 1;
    return r;
}

// Each input line's own output (no look-back).
std::vector<std::string> per_line(const Kinematics& k, const std::string& program) {
    TranslatorOptions o;
    o.input_name = "plane.gcode";
    Translator t(k, o);
    std::vector<std::string> out;
    std::uint64_t n = 0;
    for (const auto& line : lines_of(program)) {
        out.emplace_back();
        t.feed(line, ++n, out.back());
    }
    return out;
}

InputError error_of(const std::string& program) {
    const Machine m = machine("wpi5");
    const Kinematics k(m);
    try {
        per_line(k, program);
    } catch (const InputError& e) {
        return e;
    }
    FAIL("no error for:\n" << program);
    return InputError("", 0, 0, "");
}

struct Result {
    int code = -1;
    std::string out, err;
};

Result run(const TempDir& dir, const std::string& args, const std::string& env = "") {
    const fs::path out = dir.path / ".stdout", err = dir.path / ".stderr";
    const std::string cmd = "cd " + quote(dir.path.string()) + " && " + env + quote(XLATE5_BINARY) + " " + args + " </dev/null >" +
                            quote(out.string()) + " 2>" + quote(err.string());
    const int status = std::system(cmd.c_str());
    REQUIRE(status != -1);
    REQUIRE(WIFEXITED(status));
    Result r;
    r.code = WEXITSTATUS(status);
    r.out = read(out);
    r.err = read(err);
    return r;
}

// A square of side 20 at height z, printed with relative E, travel first.
std::string square(double z) {
    std::ostringstream s;
    s << "G0 X0 Y0 Z" << z + 5 << "\nG1 Z" << z << " F600\nG1 X20 E1\nG1 Y20 E1\nG1 X0 E1\nG1 Y0 E1\n";
    return s.str();
}

}  // namespace

TEST_CASE("a square printed in a plane tilted 30 degrees about X: tip and tool axis by FK in the part frame") {
    const Machine m = machine("wpi5");
    const Kinematics k(m);
    const Eigen::Vector3d origin(10, 5, 2);
    // I0 J30 K0: Rz(0) Rx(30) Rz(0).
    const Eigen::Matrix3d R = rot_z(0) * rot_x(30) * rot_z(0);
    const Eigen::Vector3d normal = R.col(2);
    CHECK(std::abs(normal.y() + std::sin(rad(30))) < 1e-12);  // +Z tipped toward -Y by 30 degrees
    const std::string program = "G21\nG90\nM83\nG0 X0 Y0 Z20\nG68.2 X10 Y5 Z2 I0 J30 K0\nG53.1\n" + square(0) + "G69\nG0 Z30\n";
    const auto out = per_line(k, program);
    const auto lines = lines_of(program);
    std::vector<double> q = m.home_joints();
    int corners = 0, pieces = 0;
    double worst_tip = 0, worst_axis = 0;
    for (std::size_t n = 0; n < lines.size(); ++n) {
        CAPTURE(lines[n]);
        for (const auto& piece : lines_of(out[n])) {
            apply_joint_lines(m, piece, q);
            if (n < 6 || n > 11 || piece.rfind("G1", 0) != 0) continue;
            // Every joint move of the square: on its plane, tool on the plane's normal.
            const Pose p = k.forward(q);
            const Eigen::Vector3d local = R.transpose() * (p.tip - origin);
            worst_axis = std::max(worst_axis, std::acos(std::clamp(p.axis.dot(normal), -1.0, 1.0)) * 180 / kPi);
            CHECK(std::abs(local.z()) < 0.01);
            CHECK(local.x() > -0.01);
            CHECK(local.x() < 20.01);
            ++pieces;
        }
        if (n >= 8 && n <= 11) {
            // The corners, by the definition: origin + R p.
            const Eigen::Vector3d corner[4] = {{20, 0, 0}, {20, 20, 0}, {0, 20, 0}, {0, 0, 0}};
            const Pose p = k.forward(q);
            worst_tip = std::max(worst_tip, (p.tip - (origin + R * corner[n - 8])).norm());
            ++corners;
        }
    }
    CHECK(corners == 4);
    CHECK(pieces >= 4);
    MESSAGE("tilted square: worst corner tip error " << worst_tip << " mm, worst axis error " << worst_axis << " deg over " << pieces
                                                     << " joint moves");
    CHECK(worst_tip < 0.001);
    CHECK(worst_axis < 0.001);
    // After G69 the plane's frame is gone: Z30 is the program frame's, the tool stays tilted.
    const Pose after = k.forward(q);
    CHECK(std::abs(after.tip.z() - 30) < 0.001);
    CHECK((after.axis - normal).norm() < 1e-6);
}

TEST_CASE("G68.2's angles are Z-X-Z about the turning axes, I first") {
    const Machine m = machine("wpi5");
    const Kinematics k(m);
    // I90 J30: the plane's X axis is +Y, its +Z (sin I sin J, -cos I sin J, cos J) = (0.5, 0, 0.866).
    // K90 then turns the plane about its own +Z: its X axis becomes Rz(90) Rx(30) Rz(90) e_x.
    for (const double K : {0.0, 90.0}) {
        CAPTURE(K);
        const Eigen::Matrix3d R = rot_z(90) * rot_x(30) * rot_z(K);
        std::ostringstream prog;
        prog << "G21\nG90\nG0 X0 Y0 Z20\nG68.2 X0 Y0 Z0 I90 J30 K" << K << "\nG53.1\nG0 X10 Y0 Z15\nG0 X0 Y10 Z15\n";
        const auto out = per_line(k, prog.str());
        std::vector<double> q = m.home_joints();
        for (std::size_t n = 0; n < out.size(); ++n) {
            apply_joint_lines(m, out[n], q);
            if (n < 5) continue;
            const Pose p = k.forward(q);
            const Eigen::Vector3d want = R * (n == 5 ? Eigen::Vector3d(10, 0, 15) : Eigen::Vector3d(0, 10, 15));
            CHECK((p.tip - want).norm() < 0.001);
            CHECK((p.axis - Eigen::Vector3d(0.5, 0, std::cos(rad(30)))).norm() < 1e-6);
        }
    }
}

TEST_CASE("arcs inside a tilted plane are the plane's") {
    const Machine m = machine("wpi5");
    const Kinematics k(m);
    const Eigen::Matrix3d R = rot_x(30);
    // A half circle of radius 10 about the plane's (10, 0): every piece at distance 10 from it.
    const std::string program = "G21\nG90\nM83\nG0 X0 Y0 Z20\nG68.2 J30\nG53.1\nG0 X0 Y0 Z0\nG2 X20 Y0 I10 J0 E3 F600\n";
    const auto out = per_line(k, program);
    std::vector<double> q = m.home_joints();
    int pieces = 0;
    for (std::size_t n = 0; n < out.size(); ++n)
        for (const auto& piece : lines_of(out[n])) {
            apply_joint_lines(m, piece, q);
            if (n != 7 || piece.rfind("G1", 0) != 0) continue;
            const Eigen::Vector3d local = R.transpose() * k.forward(q).tip;
            CHECK(std::abs(local.z()) < 0.01);
            CHECK(std::abs((local - Eigen::Vector3d(10, 0, 0)).norm() - 10) < 0.01);
            CHECK(local.y() > -0.01);  // clockwise from (0,0) to (20,0) about (10,0) passes +Y
            ++pieces;
        }
    CHECK(pieces > 4);
}

TEST_CASE("G68.2 errors: nested planes, G69 or G53.1 without one, orientation words inside one") {
    const std::string start = "G21\nG90\nG0 X0 Y0 Z20\n";
    InputError e = error_of(start + "G68.2 X1 J30\nG0 X5\nG68.2 X2 J20\n");
    CHECK(e.file() == "plane.gcode");
    CHECK(e.line() == 6);
    CHECK(e.column() == 1);
    CHECK(e.message().find("line 4") != std::string::npos);
    CHECK(e.message().find("G69") != std::string::npos);
    e = error_of(start + "G69\n");
    CHECK(e.line() == 4);
    CHECK(e.message().find("G69 without a tilted plane") != std::string::npos);
    e = error_of(start + "G68.2 J30\nG69\nG69\n");
    CHECK(e.line() == 6);
    CHECK(e.message().find("G69 without a tilted plane") != std::string::npos);
    e = error_of(start + "G53.1\n");
    CHECK(e.line() == 4);
    CHECK(e.message().find("G53.1 without a tilted plane") != std::string::npos);
    e = error_of(start + "G68.2 J30\nG53.1\nG1 X3 A10 F100\n");
    CHECK(e.line() == 6);
    CHECK(e.column() == 7);
    CHECK(e.message().find("ambiguous") != std::string::npos);
    e = error_of(start + "G43.5\nG68.2 J30\nG1 X3 I0 J0 K1 F100\n");
    CHECK(e.line() == 6);
    CHECK(e.column() == 7);
    e = error_of(start + "G68.2 J30 R5\n");
    CHECK(e.column() == 11);
    e = error_of(start + "G68.2 J30\nG92 X0\n");
    CHECK(e.line() == 5);
    // A failed G68.2 leaves no plane behind: G69 after it has nothing to cancel.
    const Machine m = machine("wpi5");
    const Kinematics k(m);
    TranslatorOptions o;
    o.input_name = "plane.gcode";
    Translator t(k, o);
    std::string out;
    t.feed("G0 X0 Y0 Z20", 1, out);
    CHECK_THROWS_AS(t.feed("G68.2 J30 Q121", 2, out), InputError);
    try {
        t.feed("G69", 3, out);
        FAIL("G69 after a refused G68.2 was accepted");
    } catch (const InputError& g69) {
        CHECK(g69.message().find("G69 without a tilted plane") != std::string::npos);
    }
}

TEST_CASE("a stamped plane: a copy onto the same stamp keeps it, any edit is copied, a copy back undoes it") {
    StampedPlane a, b;
    WorkPlane& set = a.edit();
    set.active = true;
    set.origin = Eigen::Vector3d(1, 2, 3);
    set.line = 7;
    b = a;
    CHECK(b.get().active);
    CHECK(b.get().origin == Eigen::Vector3d(1, 2, 3));
    const StampedPlane before = a;  // the look-back's copy before a line
    a.edit().tool_turned = true;    // the line changes the plane (same fields otherwise)
    b = a;
    CHECK(b.get().tool_turned);
    a = before;  // the line is undone
    CHECK_FALSE(a.get().tool_turned);
    a.edit() = WorkPlane{};  // G69: the default plane's contents under a new stamp
    b = a;
    CHECK_FALSE(b.get().active);
    b = StampedPlane{};
    CHECK_FALSE(b.get().active);
    b = before;
    CHECK(b.get().line == 7);
}

TEST_CASE("a line that cancels the plane and then fails leaves the plane, with look-back on and off") {
    const Machine m = machine("wpi5");
    const Kinematics k(m);
    for (const std::size_t lines : {std::size_t(0), Translator::kDefaultLookback}) {
        CAPTURE(lines);
        TranslatorOptions o;
        o.input_name = "plane.gcode";
        Translator t(k, o);
        t.set_lookback(lines);
        std::string out;
        t.feed("G0 X0 Y0 Z20", 1, out);
        t.feed("G68.2 J30", 2, out);
        // G69 runs first, then G53.1 finds no plane: the line is refused whole.
        CHECK_THROWS_AS(t.feed("G69 G53.1", 3, out), InputError);
        t.feed("G53.1", 4, out);  // the plane is still there to turn the tool to
        t.feed("G69", 5, out);
        CHECK_THROWS_AS(t.feed("G69", 6, out), InputError);
        t.finish(out);
    }
}

TEST_CASE("join: a base file and one whose build direction is (1,0,1), checked by FK") {
    TempDir d;
    const Machine m = machine("wpi5");
    const Kinematics k(m);
    d.write("base.gcode", "G21\nG90\nM83\nM104 S210\nG28\n" + square(0.2) + "M104 S0\nM84\n");
    d.write("sub.gcode", "G21\nG90\nM83\nG28\n" + square(0.2) + "G1 Z5\nM104 S0\n");
    const Result r = run(d, "--machine wpi5 join base.gcode sub.gcode@1,0,1@0,0,10 -o part.gcode");
    REQUIRE_MESSAGE(r.code == 0, r.err);
    const std::string out = read(d.path / "part.gcode");
    CHECK(out.rfind("; xlate5 ", 0) == 0);
    CHECK(lines_of(out)[0].find("machine=wpi5 joint space") != std::string::npos);
    // Heaters stay on and the motors powered between the parts: only the last part's M104 S0.
    std::size_t heater_off = 0;
    for (const auto& line : lines_of(out)) heater_off += line.rfind("M104 S0", 0) == 0;
    CHECK(heater_off == 1);
    CHECK(out.find("\nM84") == std::string::npos);
    // Printing moves (E > 0): the first part's on the base as written, the second's on the
    // plane through (0,0,10) with normal (1,0,1)/sqrt 2, 0.2 above it, the tool on the normal.
    const Eigen::Vector3d n = Eigen::Vector3d(1, 0, 1).normalized(), origin(0, 0, 10);
    std::vector<double> q = m.home_joints();
    std::vector<Eigen::Vector3d> base_ends, sub_ends;
    double e_total = 0;
    bool in_sub = false;
    for (const auto& line : lines_of(out)) {
        if (line.find("join: change to sub.gcode") != std::string::npos) in_sub = true;
        apply_joint_lines(m, line, q);
        if (line.empty() || line[0] == ';') continue;
        const auto w = words_of(line.substr(0, line.find(';')));
        if (!w.count('G') || w.at('G') != 1 || !w.count('E')) continue;
        e_total += w.at('E');
        const Pose p = k.forward(q);
        if (!in_sub) {
            CHECK(std::abs(p.tip.z() - 0.2) < 0.001);
            CHECK((p.axis - Eigen::Vector3d::UnitZ()).norm() < 1e-6);
            base_ends.push_back(p.tip);
        } else {
            CHECK(std::abs((p.tip - origin).dot(n) - 0.2) < 0.001);
            CHECK((p.axis - n).norm() < 1e-5);
            sub_ends.push_back(p.tip);
        }
    }
    CHECK(std::abs(e_total - 8) < 1e-6);  // every millimetre of filament of both files, once
    REQUIRE(base_ends.size() >= 4);
    REQUIRE(sub_ends.size() >= 4);
    // The second square is still a square of side 20 (its corners: the ends 20 apart in turn).
    double side_max = 0;
    for (std::size_t i = 0; i < sub_ends.size(); ++i) side_max = std::max(side_max, (sub_ends[i] - sub_ends[0]).norm());
    CHECK(std::abs(side_max - 20 * std::sqrt(2.0)) < 0.01);
    // An error in a part names the part's file and line.
    d.write("bad.gcode", "G21\nG90\nG0 X0 Y0 Z5\nG1 X1 Q3\n");
    const Result bad = run(d, "--machine wpi5 join base.gcode bad.gcode@1,0,1 -o part2.gcode");
    CHECK(bad.code == 1);
    CHECK(bad.err.rfind("bad.gcode:4:", 0) == 0);
    CHECK_FALSE(fs::exists(d.path / "part2.gcode"));
    const Result zero = run(d, "--machine wpi5 join base.gcode sub.gcode@0,0,0 -o part3.gcode");
    CHECK(zero.code == 2);
}

TEST_CASE("post-processing: FILE translated in place with the header; a translated file, binary G-code refused") {
    TempDir d;
    const std::string wall = read(fs::path(XLATE5_MACHINE_DIR_FOR_TESTS) / ".." / "examples" / "rw2_flared_wall.gcode");
    REQUIRE(!wall.empty());
    d.write("wall.gcode", wall);
    const Result reference = run(d, "--machine rw2 -i wall.gcode -o ref.gcode");
    REQUIRE(reference.code == 0);
    const Result in_place = run(d, "--machine rw2 wall.gcode");
    REQUIRE_MESSAGE(in_place.code == 0, in_place.err);
    const std::string translated = read(d.path / "wall.gcode");
    CHECK(translated == read(d.path / "ref.gcode"));
    CHECK(lines_of(translated)[0].rfind("; xlate5 ", 0) == 0);
    CHECK(lines_of(translated)[0].find(" machine=rw2 joint space") != std::string::npos);
    for (const auto& name : d.entries()) CHECK((name[0] == '.' || name == "ref.gcode" || name == "wall.gcode"));  // no temporary left
    // Translated again: refused, the file untouched; --force does it.
    const Result again = run(d, "--machine rw2 wall.gcode");
    CHECK(again.code == 1);
    CHECK(again.err.find("wall.gcode:1:1:") == 0);
    CHECK(again.err.find("--force") != std::string::npos);
    CHECK(read(d.path / "wall.gcode") == translated);
    // The slicer's final name is the one errors give.
    const Result named = run(d, "--machine rw2 wall.gcode", "SLIC3R_PP_OUTPUT_NAME=/home/u/wall_final.gcode ");
    CHECK(named.err.find("/home/u/wall_final.gcode:1:1:") == 0);
    // A preview (--inverse) read back is a translation's input: its header is replaced.
    const Result preview = run(d, "--machine rw2 --inverse -i ref.gcode -o preview.gcode");
    REQUIRE(preview.code == 0);
    CHECK(lines_of(read(d.path / "preview.gcode"))[0].find(" machine=rw2 tool space") != std::string::npos);
    const Result back = run(d, "--machine rw2 -i preview.gcode -o back.gcode");
    REQUIRE(back.code == 0);
    CHECK(lines_of(read(d.path / "back.gcode"))[0] == lines_of(translated)[0]);
    CHECK(read(d.path / "back.gcode").find("tool space") == std::string::npos);
    // --inverse of a tool-space file is refused the same way.
    const Result inverse_twice = run(d, "--machine rw2 --inverse -i preview.gcode -o x.gcode");
    CHECK(inverse_twice.code == 1);
    CHECK_FALSE(fs::exists(d.path / "x.gcode"));
    // --force translates it anyway (here a file that is joint space only by its header).
    d.write("t.gcode", lines_of(translated)[0] + "\nG21\nG90\n");
    CHECK(run(d, "--machine rw2 t.gcode").code == 1);
    const Result forced = run(d, "--machine rw2 --force t.gcode");
    CHECK(forced.code == 0);
    CHECK(lines_of(read(d.path / "t.gcode"))[0] == lines_of(translated)[0]);
    // Binary G-code: refused with the setting to change, the file untouched.
    const std::string binary = std::string("GCDE\x01\x00\x00\x00\x00\x00", 10) + "\n G1 X1\n";
    d.write("b.bgcode", binary);
    const Result bin = run(d, "--machine rw2 b.bgcode");
    CHECK(bin.code == 1);
    CHECK(bin.err.find("binary_gcode") != std::string::npos);
    CHECK(read(d.path / "b.bgcode") == binary);
    // FILE together with -i or -o is ambiguous.
    CHECK(run(d, "--machine rw2 wall.gcode -o y.gcode").code == 2);
}

TEST_CASE("post-processing: PrusaSlicer slices a generated cube with xlate5 as its post-processing script") {
    if (std::system("command -v prusa-slicer >/dev/null 2>&1") != 0) {
        MESSAGE("skipped: prusa-slicer is not installed (scripts/install-deps.sh installs it)");
        return;
    }
    TempDir d;
    d.write("cube.stl", cube_stl(20));
    const std::string slice = "prusa-slicer --export-gcode cube.stl --center 100,100 ";
    const std::string script = std::string(XLATE5_BINARY) + " --machine rw2 --no-progress";
    auto sh = [&](const std::string& cmd) { return std::system(("cd " + quote(d.path.string()) + " && " + cmd + " >/dev/null 2>&1").c_str()); };
    REQUIRE(sh(slice + "-o raw.gcode") == 0);
    REQUIRE(sh(slice + "--post-process " + quote(script) + " -o cube.gcode") == 0);
    REQUIRE(run(d, "--machine rw2 -i raw.gcode -o ref.gcode").code == 0);
    // The slicer's file is the translation of what it sliced (its time stamp and the setting
    // that names the script aside).
    auto without_stamp = [](const std::string& text) {
        std::string kept;
        for (const auto& line : lines_of(text))
            if (line.rfind("; generated by PrusaSlicer", 0) != 0 && line.rfind("; post_process =", 0) != 0) kept += line + "\n";
        return kept;
    };
    const std::string got = read(d.path / "cube.gcode");
    CHECK(lines_of(got).at(0).find(" machine=rw2 joint space") != std::string::npos);
    CHECK(lines_of(got).size() > 1000);
    CHECK(without_stamp(got) == without_stamp(read(d.path / "ref.gcode")));
    // Run as a post-processing script again on it: refused, unchanged.
    CHECK(run(d, "--machine rw2 cube.gcode").code == 1);
    CHECK(read(d.path / "cube.gcode") == got);
}
