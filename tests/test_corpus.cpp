// SPDX-License-Identifier: GPL-3.0-or-later
// Whole-file runs over the real third-party files in ../shared/corpus (loaded at test time,
// never copied here): what xlate5 accepts translates faithfully, what it cannot accept stops
// with file:line:column and a cause, never a crash.
#include <doctest/doctest.h>

#include <cctype>
#include <cmath>
#include <fcntl.h>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <unistd.h>

#include "helpers.hpp"
#include "translators/error.hpp"
#include "translators/inputs/gcode_lexer.hpp"
#include "translators/kinematics/kinematics.hpp"
#include "translators/machine/machine.hpp"
#include "translators/pipeline/stream.hpp"
#include "translators/pipeline/translator.hpp"

using namespace xlate5;
namespace fs = std::filesystem;

namespace {

std::string corpus(const std::string& rel) { return xlate5::test::corpus_dir() + "/" + rel; }

struct Run {
    bool ok = false;
    std::string error;
    std::uint64_t error_line = 0;
    std::uint32_t error_column = 0;
    std::string output;
};

Run translate_file(const Machine& m, const std::string& path, TranslatorOptions options = {}) {
    const Kinematics k(m);
    options.input_name = path;
    Translator t(k, options);
    Run run;
    std::ifstream in(path, std::ios::binary);
    REQUIRE(in);
    std::string line;
    std::uint64_t n = 0;
    try {
        while (std::getline(in, line)) t.feed(line, ++n, run.output);
        run.ok = true;
    } catch (const InputError& e) {
        run.error = e.what();
        run.error_line = e.line();
        run.error_column = e.column();
    }
    return run;
}

Run translate_file(const std::string& machine, const std::string& path, TranslatorOptions options = {}) {
    return translate_file(load_machine(std::string(XLATE5_MACHINE_DIR_FOR_TESTS) + "/" + machine + ".toml"), path, std::move(options));
}

std::string line_of(const std::string& path, std::uint64_t n) {
    std::ifstream in(path, std::ios::binary);
    std::string line;
    for (std::uint64_t i = 0; i < n && std::getline(in, line); ++i) {}
    return line;
}

// Sum of E over a file in the given E mode (absolute files: the sum of increments, with G92 E
// resets), read with xlate5's own lexer but independently of the translator.
double total_extrusion(const std::string& text) {
    std::istringstream in(text);
    std::string line;
    Block b;
    bool relative = false;
    double last = 0, total = 0;
    while (std::getline(in, line)) {
        lex_line(line, b);
        int g = -1, m = -1;
        const Word* e = nullptr;
        for (const auto& w : b.words()) {
            if (w.letter == 'G') g = int(std::lround(w.value * 10));
            else if (w.letter == 'M') m = int(std::lround(w.value * 10));
            else if (w.letter == 'E') e = &w;
        }
        if (m == 820 || g == 900) relative = false;
        if (m == 830 || g == 910) relative = true;
        if (!e || !e->has_value) continue;
        if (g == 920) last = e->value;
        else if (g == 0 || g == 10) {
            total += relative ? e->value : e->value - last;
            if (!relative) last = e->value;
        }
    }
    return total;
}

std::string read(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    std::ostringstream s;
    s << in.rdbuf();
    return s.str();
}

// "path:line:column: cause" with numeric line and column.
bool has_error_place(const std::string& e, const std::string& path) {
    if (e.rfind(path + ":", 0) != 0) return false;
    std::size_t i = path.size() + 1;
    for (int field = 0; field < 2; ++field) {
        const std::size_t start = i;
        while (i < e.size() && std::isdigit(static_cast<unsigned char>(e[i]))) ++i;
        if (i == start || i >= e.size() || e[i] != ':') return false;
        ++i;
    }
    return e.size() > i + 1 && e[i] == ' ';
}

}  // namespace

TEST_CASE("the corpus is where the tests expect it" * doctest::skip(xlate5::test::corpus_absent())) {
    for (const char* f : {"planar/dino_prusaslicer-2.9.2.gcode", "planar/pi_3mm_deformed_tet_cura-5.8.0.gcode", "s4/pi_3mm_side_paint_rtheta.gcode",
                          "s3deformfdm/ring_Gcode.txt", "linuxcnc/metric_pipe.ngc", "nx_cldata/APT_Variable_Axis.cls"})
        REQUIRE_MESSAGE(fs::exists(corpus(f)), corpus(f));
}

TEST_CASE("planar slicer files translate on table-table machines with E and every move kept" * doctest::skip(xlate5::test::corpus_absent())) {
    for (const std::string file : {"planar/dino_prusaslicer-2.9.2.gcode", "planar/pi_3mm_deformed_tet_cura-5.8.0.gcode"}) {
        for (const std::string machine : {"pentarod", "koc5", "xyzac-trt", "wpi5"}) {
            CAPTURE(file);
            CAPTURE(machine);
            const std::string path = corpus(file);
            const Run run = translate_file(machine, path);
            REQUIRE_MESSAGE(run.ok, run.error);
            const std::string input = read(path);
            // Extrusion passes through exactly.
            CHECK(total_extrusion(run.output) == doctest::Approx(total_extrusion(input)).epsilon(1e-12));
            // Every input line that is not a move passes through unchanged and in order: the
            // M/T lines of both files are the same sequence.
            auto mt = [](const std::string& text) {
                std::istringstream in(text);
                std::string line, seq;
                while (std::getline(in, line)) {
                    if (!line.empty() && line.back() == '\r') line.pop_back();
                    // M82/M83 are excluded: xlate5 states the E mode after every G90/G91.
                    if (!line.empty() && (line[0] == 'M' || line[0] == 'T') && line.rfind("M82", 0) && line.rfind("M83", 0)) seq += line + "\n";
                }
                return seq;
            };
            CHECK(mt(run.output) == mt(input));
        }
    }
}

TEST_CASE("planar tool-space moves land where FK says: the inverse of the output is the input path" * doctest::skip(xlate5::test::corpus_absent())) {
    const std::string path = corpus("planar/pi_3mm_deformed_tet_cura-5.8.0.gcode");
    const Run fwd = translate_file("wpi5", path);  // the plate moves: joints are far from the tip values
    REQUIRE_MESSAGE(fwd.ok, fwd.error);
    const Machine m = load_machine(std::string(XLATE5_MACHINE_DIR_FOR_TESTS) + "/wpi5.toml");
    const Kinematics k(m);
    TranslatorOptions inv;
    inv.inverse = true;
    Translator back(k, inv);
    std::string tool;
    std::istringstream in(fwd.output);
    std::string line;
    std::uint64_t n = 0;
    while (std::getline(in, line)) back.feed(line, ++n, tool);
    // Replay the input's X Y Z (modal, absolute) and the recovered tool space side by side.
    auto tips = [](const std::string& text) {
        std::vector<std::array<double, 3>> out;
        std::istringstream s(text);
        std::string l;
        Block b;
        std::array<double, 3> p{0, 0, 0};
        while (std::getline(s, l)) {
            lex_line(l, b);
            bool move = false, xyz = false;
            for (const auto& w : b.words()) {
                if (w.letter == 'G' && (w.value == 0 || w.value == 1)) move = true;
                if (w.letter >= 'X' && w.letter <= 'Z') {
                    p[std::size_t(w.letter - 'X')] = w.value;
                    xyz = true;
                }
            }
            if (move && xyz) out.push_back(p);
        }
        return out;
    };
    const auto a = tips(read(path));
    const auto b = tips(tool);
    REQUIRE(a.size() > 10000);
    // Zero-length moves are not re-sent, so compare the sequence of distinct positions.
    auto distinct = [](std::vector<std::array<double, 3>> v) {
        std::vector<std::array<double, 3>> o;
        for (const auto& p : v)
            if (o.empty() || std::abs(o.back()[0] - p[0]) + std::abs(o.back()[1] - p[1]) + std::abs(o.back()[2] - p[2]) > 2e-3) o.push_back(p);
        return o;
    };
    const auto da = distinct(a), db = distinct(b);
    for (std::size_t i = 0; i < std::min(da.size(), db.size()); ++i) {
        if (std::abs(da[i][0] - db[i][0]) + std::abs(da[i][1] - db[i][1]) + std::abs(da[i][2] - db[i][2]) > 1e-3) {
            MESSAGE("first difference at " << i << ": " << da[i][0] << " " << da[i][1] << " " << da[i][2] << " vs " << db[i][0] << " " << db[i][1] << " " << db[i][2]);
            break;
        }
    }
    REQUIRE(da.size() == db.size());
    double worst = 0;
    for (std::size_t i = 0; i < da.size(); ++i)
        for (int c = 0; c < 3; ++c) worst = std::max(worst, std::abs(da[i][c] - db[i][c]));
    CHECK(worst < 1e-3);  // joints are written with 4 decimals on wpi5
}

TEST_CASE("joint-space multi-axis files pass through under G49" * doctest::skip(xlate5::test::corpus_absent())) {
    // S4's R-theta file: C X Z B words, G93/G94 switches, two tools, a joined header line.
    TranslatorOptions o;
    o.start_mode = OrientationMode::Joints;
    const Run run = translate_file("koc5", corpus("s4/pi_3mm_side_paint_rtheta.gcode"), o);
    REQUIRE_MESSAGE(run.ok, run.error);
    CHECK(total_extrusion(run.output) == doctest::Approx(total_extrusion(read(corpus("s4/pi_3mm_side_paint_rtheta.gcode")))).epsilon(1e-12));
    // Every G93 and G94 switch reaches the firmware in order.
    auto count = [](const std::string& s, const std::string& what) {
        std::size_t n = 0;
        for (std::size_t at = s.find(what); at != std::string::npos; at = s.find(what, at + 1)) ++n;
        return n;
    };
    CHECK(count(run.output, "\nG93\n") == 319);
}

TEST_CASE("the inverse reads the S3-DeformFDM ring's CNC preamble, G49 included, and stops where the joint-space translation does" *
          doctest::skip(xlate5::test::corpus_absent())) {
    // The ring (Zhang et al., SIGGRAPH Asia 2022) starts G21 G40 G49 G80 G90: G49 cancels tool
    // length compensation, so its X Y Z B C words are the machine's joints, which is what the
    // inverse reads. Both directions read it as joint space (the extruder on A) on koc5 (B C).
    const std::string path = corpus("s3deformfdm/ring_Gcode.txt");
    REQUIRE(line_of(path, 3) == "G49");
    TranslatorOptions joints, inverse;
    joints.start_mode = OrientationMode::Joints;
    joints.extruder_letter = inverse.extruder_letter = 'A';
    inverse.inverse = true;
    const Run forward = translate_file("koc5", path, joints), back = translate_file("koc5", path, inverse);
    CAPTURE(forward.error);
    CAPTURE(back.error);
    CHECK(back.ok == forward.ok);
    CHECK(back.error_line == forward.error_line);  // the same line refused, if any, for the same cause
    if (!forward.ok) {
        CHECK(back.error_line > 3);
        CHECK(back.error.find("outside its limits") != std::string::npos);
        CHECK(forward.error.find("outside its limits") != std::string::npos);
    }

    // koc5 with room for the ring's Z250 (its travel height; koc5 stops at 200): the inverse reads
    // the whole file, and its tool-space output translated forward again (one joint move per
    // move) gives the joints the joint-space translation wrote, to their last written digit.
    Machine roomy = load_machine(std::string(XLATE5_MACHINE_DIR_FOR_TESTS) + "/koc5.toml");
    roomy.joints[std::size_t(roomy.joint_index('Z'))].max = 300;
    roomy.motion.segment = false;
    const Run wide_forward = translate_file(roomy, path, joints), wide_back = translate_file(roomy, path, inverse);
    REQUIRE_MESSAGE(wide_forward.ok, wide_forward.error);
    REQUIRE_MESSAGE(wide_back.ok, wide_back.error);
    // Nothing of G49 reaches the tool-space output (there it would mean joints again).
    for (const auto& l : xlate5::test::lines_of(wide_back.output)) CHECK(l.rfind("G49", 0) != 0);
    const Kinematics k(roomy);
    TranslatorOptions angles;
    angles.start_mode = OrientationMode::Angles;
    Translator again(k, angles);
    std::string round;
    std::uint64_t n = 0;
    for (const auto& l : xlate5::test::lines_of(wide_back.output)) again.feed(l, ++n, round);
    std::vector<double> q1 = roomy.home_joints(), q2 = q1;
    std::size_t moves = 0;
    double worst = 0;
    const auto moves_of = [](const std::string& text) {
        std::vector<std::string> m;
        for (const auto& l : xlate5::test::lines_of(text))
            if (l.rfind("G0 ", 0) == 0 || l.rfind("G1 ", 0) == 0) m.push_back(l);
        return m;
    };
    const auto first = moves_of(wide_forward.output), second = moves_of(round);
    REQUIRE(first.size() == second.size());
    for (std::size_t i = 0; i < first.size(); ++i) {
        xlate5::test::apply_joint_lines(roomy, first[i], q1);
        xlate5::test::apply_joint_lines(roomy, second[i], q2);
        for (std::size_t j = 0; j < q1.size(); ++j) worst = std::max(worst, std::abs(q1[j] - q2[j]));
        ++moves;
    }
    MESSAGE("ring: " << moves << " joint moves, inverse and forward again within " << worst << " of the joint-space translation");
    CHECK(moves > 60000);
    CHECK(worst <= 1e-3);
}

TEST_CASE("files xlate5 cannot accept fail at the right line with a cause" * doctest::skip(xlate5::test::corpus_absent())) {
    struct Case {
        const char* machine;
        const char* file;
        const char* cause;
        TranslatorOptions options;
    };
    TranslatorOptions joints_a;
    joints_a.start_mode = OrientationMode::Joints;
    joints_a.extruder_letter = 'A';
    TranslatorOptions joints_e;
    joints_e.start_mode = OrientationMode::Joints;
    const Case cases[] = {
        {"rw2", "linuxcnc/metric_pipe.ngc", "parameters and expressions are not supported", {}},
        {"rw2", "nx_cldata/APT_Variable_Axis.cls", "is not a G-code word", {}},
        {"rw2", "s4/pi_3mm_side_paint_rtheta.gcode", "not a tool-space word", {}},
        {"koc5", "s3deformfdm/ring_Gcode.txt", "outside its limits", joints_a},
        {"rw2", "s3deformfdm/ring_Gcode.txt", "not a joint", joints_e},
    };
    for (const Case& c : cases) {
        CAPTURE(c.file);
        const std::string path = corpus(c.file);
        const Run run = translate_file(c.machine, path, c.options);
        REQUIRE_FALSE(run.ok);
        CHECK(has_error_place(run.error, path));
        CHECK(run.error.rfind(path + ":" + std::to_string(run.error_line) + ":", 0) == 0);
        CHECK(run.error.find(c.cause) != std::string::npos);
        // The column points into the line it names.
        CHECK(run.error_column >= 1);
        CHECK(run.error_column <= line_of(path, run.error_line).size());
    }
}
