// SPDX-License-Identifier: GPL-3.0-or-later
// The collision check (pipeline/collide.hpp) and the machine's bodies (machine/geometry.hpp):
// constructed collisions and their near misses on the bundled machines, the sweep between a
// move's ends, the sweep against dense sampling, the look-back's replay, and real files.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <sys/wait.h>
#include <filesystem>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "helpers.hpp"
#include "translators/error.hpp"
#include "translators/kinematics/kinematics.hpp"
#include "translators/machine/machine.hpp"
#include "translators/pipeline/collide.hpp"
#include "translators/pipeline/collide_bodies.hpp"
#include "translators/pipeline/translator.hpp"

using namespace xlate5;
namespace fs = std::filesystem;

namespace {

std::string machine_path(const std::string& name) { return std::string(XLATE5_MACHINE_DIR_FOR_TESTS) + "/" + name + ".toml"; }

std::vector<std::string> lines_of(const std::string& text) {
    std::vector<std::string> out;
    std::istringstream in(text);
    for (std::string l; std::getline(in, l);) out.push_back(l);
    return out;
}

// Feeds `text` to a fresh translator; returns the error ("" when none) and counts collisions.
struct Outcome {
    std::string error;
    std::string output;
    std::vector<CollisionEvent> found;
    std::size_t beads = 0;
};
Outcome run(const Kinematics& k, const std::string& text, CollisionPolicy policy = CollisionPolicy::Refuse,
            std::size_t lookback = 0, std::optional<OrientationMode> mode = std::nullopt, char extruder = 'E') {
    Outcome o;
    TranslatorOptions opt;
    opt.input_name = "in.gcode";
    opt.collision = policy;
    opt.start_mode = mode;
    opt.extruder_letter = extruder;
    opt.on_collision = [&o](const CollisionEvent& e) { o.found.push_back(e); };
    Translator t(k, opt);
    if (lookback) t.set_lookback(lookback);
    std::uint64_t n = 0;
    try {
        for (const auto& l : lines_of(text)) t.feed(l, ++n, o.output);
        t.finish(o.output);
    } catch (const InputError& e) {
        o.error = e.what();
    }
    if (t.collision()) o.beads = t.collision()->beads();
    return o;
}

using test::load_with_bodies;  // tests/helpers.hpp: the test bodies, and why they are not shipped
using test::rw2_wall;

}  // namespace

TEST_CASE("bodies: read from the machine file, with clear errors") {
    const Machine m = load_with_bodies("rw2");
    REQUIRE(m.geometry);
    CHECK(m.geometry->bodies.size() == 5);
    CHECK(m.geometry->settings.tip_clearance == 1.0);
    // The bed rides on the part chain's end (rw2 has none: the base), the head's parts on the tip.
    for (const auto& b : m.geometry->bodies) CHECK(b.after == (b.tool_side ? int(m.tool_chain.size()) - 1 : -1));

    const std::string base = read_machine_file(machine_path("rw2")) + "\n" + test::read(fs::path(XLATE5_MACHINE_DIR_FOR_TESTS).parent_path() / "tests" / "bodies" / "rw2.toml");
    auto error_of = [&](const std::string& extra) {
        try {
            (void)load_machine_text(base + extra, "m.toml");
        } catch (const MachineError& e) {
            return std::string(e.what());
        }
        return std::string();
    };
    const int lines = int(std::count(base.begin(), base.end(), '\n'));
    const std::string at = "m.toml:" + std::to_string(lines + 2) + ": ";
    CHECK(error_of("\n[[bodies]]\nname = \"x\"\nside = \"tool\"\nshape = \"boxx\"\nsize = [1, 1, 1]\ntranslate = [0, 0, 5]\n") ==
          "m.toml:" + std::to_string(lines + 5) + ": bodies[5].shape: expected box, cylinder, cone, capsule, sphere or mesh; did you mean 'box'?");
    CHECK(error_of("\n[[bodies]]\nname = \"x\"\nside = \"tool\"\nshape = \"cylinder\"\nlength = 3\ntranslate = [0, 0, 5]\n") ==
          at + "bodies[5]: a cylinder needs radius");
    CHECK(error_of("\n[[bodies]]\nname = \"x\"\nside = \"part\"\nafter = \"B\"\nshape = \"sphere\"\nradius = 3\n")
              .find("bodies[5].after: expected \"base\" or a joint letter of the part_chain") != std::string::npos);
    // Below tip_clearance (1 mm): a sphere of radius 3 about a point 2 mm above the tip.
    CHECK(error_of("\n[[bodies]]\nname = \"x\"\nside = \"tool\"\nshape = \"sphere\"\nradius = 3\ntranslate = [0, 0, 2]\n") ==
          at + "bodies[5]: reaches -1 mm along the tool axis from the tip, below collision.tip_clearance (1 mm): start it at tip_clearance or above");
    CHECK(error_of("\n[[bodies]]\nname = \"x\"\nside = \"tool\"\nshape = \"mesh\"\nmesh = \"nowhere.stl\"\n").find("cannot read the mesh") !=
          std::string::npos);
    CHECK(error_of("\n[[bodies]]\nname = \"bed\"\nside = \"part\"\nshape = \"sphere\"\nradius = 3\n").find("body 'bed' is defined twice") !=
          std::string::npos);
}

TEST_CASE("bodies: a mesh beside the machine file is read by assimp and cut at tip_clearance") {
    test::TempDir dir;
    // A closed tetrahedron-like pyramid, apex at the tip, 10 mm tall: STL text.
    dir.write("cone.stl",
              "solid c\n"
              "facet normal 0 0 0\nouter loop\nvertex 0 0 0\nvertex 5 0 10\nvertex 0 5 10\nendloop\nendfacet\n"
              "facet normal 0 0 0\nouter loop\nvertex 0 0 0\nvertex 0 5 10\nvertex -5 -5 10\nendloop\nendfacet\n"
              "facet normal 0 0 0\nouter loop\nvertex 0 0 0\nvertex -5 -5 10\nvertex 5 0 10\nendloop\nendfacet\n"
              "facet normal 0 0 0\nouter loop\nvertex 5 0 10\nvertex -5 -5 10\nvertex 0 5 10\nendloop\nendfacet\n"
              "endsolid c\n");
    const std::string text = read_machine_file(machine_path("rw2")) + "\n" + test::read(fs::path(XLATE5_MACHINE_DIR_FOR_TESTS).parent_path() / "tests" / "bodies" / "rw2.toml") +
                             "\n[[bodies]]\nname = \"drawn nozzle\"\nside = \"tool\"\nshape = \"mesh\"\nmesh = \"cone.stl\"\n";
    const auto path = dir.write("m.toml", text);
    const Machine m = load_machine(path.string());
    const Body& b = m.geometry->bodies.back();
    REQUIRE(b.shape.kind == BodyShape::Kind::Mesh);
    double low = 1e9, high = -1e9;
    for (const auto& v : b.shape.vertices) low = std::min(low, v.z()), high = std::max(high, v.z());
    CHECK(low == doctest::Approx(1.0));  // cut at tip_clearance
    CHECK(high == doctest::Approx(10.0));
}

TEST_CASE("rw2: the head tilted toward a wall printed earlier is refused; less tilt passes") {
    const Machine m = load_with_bodies("rw2");
    const Kinematics k(m);
    const std::string wall = rw2_wall();
    // Beside the wall (its face at X 49.78: X 50 less half the bead's width), the tip 10 mm
    // off it, on the wall's top layer's height. B leans the head toward +X, onto the wall: at 60
    // degrees the heater block (16 mm wide, from 5 mm above the tip) comes down on its top.
    auto beside = [&](int b) {
        return wall + "G1 X38 Y100 Z20 B" + std::to_string(b) + "\nG1 Z6.2\nG1 X38 Y110 E0.5\n";
    };
    const Outcome hit = run(k, beside(60));
    const int at_line = int(lines_of(wall).size()) + 1;  // the move down beside the wall
    CHECK(hit.error.rfind("in.gcode:" + std::to_string(at_line + 1) + ":1: collision: heater block meets printed part at line ", 0) == 0);
    CHECK(hit.error.find(" at X4") != std::string::npos);  // on the wall's side (X 49.8)
    const Outcome miss = run(k, beside(30));
    CHECK(miss.error == "");
    // Warned, not refused: every line is written, the collision told.
    const Outcome warned = run(k, beside(60), CollisionPolicy::Warn);
    CHECK(warned.error == "");
    CHECK(!warned.found.empty());
    CHECK(run(k, beside(60), CollisionPolicy::Off).error == "");
}

TEST_CASE("rw2: the bed at low Z with a large tilt is refused; higher up passes") {
    const Machine m = load_with_bodies("rw2");
    const Kinematics k(m);
    // B 80 lays the head nearly flat: the heat sink (radius 11 mm, 20 to 46 mm along the tool
    // axis) then reaches cos(80) * 20 - 11 sin(80) = -7.4 mm below the tip. At Z 5 it meets the bed.
    const std::string start = "G21\nG90\nG43.4\nG1 X100 Y100 Z30 A0 B0 F3000\nG1 B80\n";
    const Outcome low = run(k, start + "G1 Z5\n");
    CHECK(low.error.find("in.gcode:6:1: collision: ") == 0);
    CHECK(low.error.find(" meets bed at ") != std::string::npos);
    CHECK(run(k, start + "G1 Z10\n").error == "");
}

TEST_CASE("rw2: the sweep finds a contact between a move's ends where neither end touches") {
    const Machine m = load_with_bodies("rw2");
    const Kinematics k(m);
    TranslatorOptions opt;
    opt.start_mode = OrientationMode::Angles;
    opt.reroute = false;  // the travel below is refused, not lifted round the wall
    Translator t(k, opt);
    std::string out;
    std::uint64_t n = 0;
    for (const auto& l : lines_of(rw2_wall() + "G1 X40 Y100 Z2\n")) t.feed(l, ++n, out);
    CollisionStage* stage = t.collision();
    REQUIRE(stage);
    CHECK(stage->beads() == 30);
    const std::vector<double> q0 = t.joints();
    Pose far;
    far.tip = Eigen::Vector3d(60, 100, 2);
    far.axis = Eigen::Vector3d::UnitZ();
    std::vector<double> q1;
    REQUIRE(k.inverse(far, q0, q1).ok());
    // Both ends clear the wall by millimetres; the nozzle's cone (1 to 5 mm above the tip, so
    // Z 3 to 7) passes through the wall (up to Z 6) half way.
    CHECK(stage->clearance(q0) > 1.0);
    CHECK(stage->clearance(q1) > 1.0);
    const auto ev = stage->sweep(q0, q1);
    REQUIRE(ev);
    CHECK(ev->tool_body == "nozzle");
    CHECK(ev->bead_line > 0);
    CHECK(ev->at.x() == doctest::Approx(50).epsilon(0.02));
    // The translator refuses the same move, and the line leaves no bead behind.
    std::string more;
    CHECK_THROWS_WITH_AS(t.feed("G0 X60 Y100 Z2", ++n, more), doctest::Contains("collision: nozzle meets printed part at line"), InputError);
    CHECK(stage->beads() == 30);
    // The translator goes on after the refused line as if it never came (the service refuses
    // such a line to its sender and goes on): over the wall instead, clear, and printing on.
    CHECK_NOTHROW(t.feed("G0 X40 Y100 Z10", ++n, more));
    CHECK_NOTHROW(t.feed("G0 X60 Y100 Z10", ++n, more));
    CHECK_NOTHROW(t.feed("G0 Z0.2", ++n, more));
    CHECK_NOTHROW(t.feed("G1 X60 Y110 E1", ++n, more));
    CHECK(stage->beads() > 30);
}

// The joints of every move line in `text` (G0/G1, modal from `q`), in order.
std::vector<std::vector<double>> written_moves(const Machine& m, const std::string& text, std::vector<double> q) {
    std::vector<std::vector<double>> out;
    for (const auto& l : lines_of(text)) {
        if (l.rfind("G0 ", 0) != 0 && l.rfind("G1 ", 0) != 0) continue;
        std::istringstream words(l.substr(3));
        for (std::string w; words >> w;)
            for (std::size_t j = 0; j < m.joints.size(); ++j)
                if (w[0] == m.joints[j].output) q[j] = std::stod(w.substr(1));
        out.push_back(q);
    }
    return out;
}

TEST_CASE("rw2: a travel through the wall is re-routed: lifted along the tool axis, across, lowered, all clear") {
    const Machine m = load_with_bodies("rw2");
    const Kinematics k(m);
    const double lift = m.geometry->settings.lift;
    std::vector<CollisionEvent> told;
    TranslatorOptions opt;
    opt.start_mode = OrientationMode::Angles;
    opt.on_collision = [&](const CollisionEvent& e) { told.push_back(e); };
    Translator t(k, opt);
    std::string out;
    std::uint64_t n = 0;
    // Beside the wall (X 50, up to Z 6): a
    // travel across it at Z 2.
    for (const auto& l : lines_of(rw2_wall() + "G1 X40 Y100 Z20 B0\nG1 Z2\n")) t.feed(l, ++n, out);
    CollisionStage& stage = *t.collision();
    const std::vector<double> q0 = t.joints();
    const std::size_t beads = stage.beads();
    std::string more;
    REQUIRE_NOTHROW(t.feed("G0 X60 Y100 Z2", ++n, more));
    REQUIRE(told.size() == 1);
    CHECK(told[0].rerouted);
    CHECK(told[0].line == n);
    CHECK(told[0].lift == lift);
    CHECK(told[0].message().find("travel re-routed, lifted 10.000 mm: ") == 0);
    CHECK(stage.beads() == beads);  // a travel lays nothing
    // The written path, read back: three moves, by forward kinematics of the written joints.
    const auto moves = written_moves(m, more, q0);
    REQUIRE(moves.size() == 3);
    const Pose start = k.forward(q0), up0 = k.forward(moves[0]), up1 = k.forward(moves[1]), end = k.forward(moves[2]);
    const double digits = 2e-3;  // the written joints' three decimals
    CHECK((up0.tip - (start.tip + lift * start.axis)).norm() < digits);
    CHECK((up0.axis - start.axis).norm() < 1e-4);
    CHECK((end.tip - Eigen::Vector3d(60, 100, 2)).norm() < digits);
    CHECK((up1.tip - (end.tip + lift * end.axis)).norm() < digits);
    CHECK((up1.axis - end.axis).norm() < 1e-4);
    CHECK(up0.tip.z() > 6);  // above the wall
    // Every leg clear of the wall at every one of 400 samples (the joints move linearly).
    std::vector<double> prev = q0, q(q0.size());
    double least = 1e300;
    for (const auto& to : moves) {
        for (int s = 0; s <= 400; ++s) {
            for (std::size_t j = 0; j < q.size(); ++j) q[j] = prev[j] + (to[j] - prev[j]) * s / 400;
            least = std::min(least, stage.clearance(q));
        }
        prev = to;
    }
    CHECK(least > 0);
    // Re-routing off: the same travel is refused.
    TranslatorOptions off = opt;
    off.reroute = false;
    Translator refused(k, off);
    std::string ignored;
    n = 0;
    for (const auto& l : lines_of(rw2_wall() + "G1 X40 Y100 Z20 B0\nG1 Z2\n")) refused.feed(l, ++n, ignored);
    CHECK_THROWS_WITH_AS(refused.feed("G0 X60 Y100 Z2", ++n, ignored), doctest::Contains("collision: "), InputError);
}

namespace {
// rw2 with its test bodies under --collision warn, the wall printed: the part the property
// tests sweep pieces against.
struct WallPrinted {
    Machine m = load_with_bodies("rw2");
    Kinematics k{m};
    Translator t{k, [] {
        TranslatorOptions opt;
        opt.collision = CollisionPolicy::Warn;
        return opt;
    }()};
    WallPrinted() {
        std::string out;
        std::uint64_t n = 0;
        for (const auto& l : lines_of(rw2_wall())) t.feed(l, ++n, out);
    }
};
}  // namespace

TEST_CASE("rw2: the sweep never misses what dense sampling finds (property)") {
    WallPrinted wall;
    CollisionStage& stage = *wall.t.collision();
    std::mt19937 rng(38);
    std::uniform_real_distribution<double> U(0, 1);
    int hits = 0, misses = 0;
    for (int i = 0; i < 150; ++i) {
        // Pieces near the wall: tip X 30..70, Y 90..110, Z 1..15, A and B turning by up to 60.
        auto q_at = [&] {
            return std::vector<double>{30 + 40 * U(rng), 90 + 20 * U(rng), 1 + 14 * U(rng), -60 + 120 * U(rng), -60 + 120 * U(rng)};
        };
        const std::vector<double> q0 = q_at(), q1 = q_at();
        constexpr int kSamples = 400;
        double least = 1e300;
        std::vector<double> q(5);
        for (int s = 0; s <= kSamples; ++s) {
            for (int j = 0; j < 5; ++j) q[std::size_t(j)] = q0[std::size_t(j)] + (q1[std::size_t(j)] - q0[std::size_t(j)]) * s / kSamples;
            least = std::min(least, stage.clearance(q));
        }
        const bool swept = bool(stage.sweep(q0, q1));
        if (least <= 0) CHECK(swept);  // conservative: a sampled contact is always found
        // Exact enough: what the sweep finds is near contact somewhere (samples are at most
        // 1/400 of the piece apart: a few tenths of a millimetre here).
        if (swept) CHECK(least < 1.0);
        (swept ? hits : misses)++;
    }
    MESSAGE("sweeps with a contact: " << hits << ", without: " << misses);
    CHECK(hits > 10);
    CHECK(misses > 10);
}

TEST_CASE("rw2: chained pieces, each starting where the last ended, never miss what dense sampling finds") {
    // The check carries each pair's clearance from piece to piece while they chain (the
    // odometers of collide.cpp): a random walk near the wall, each piece against dense samples.
    WallPrinted wall;
    CollisionStage& stage = *wall.t.collision();
    std::mt19937 rng(3838);
    std::uniform_real_distribution<double> U(-1, 1);
    const double lo[5] = {38, 90, 1, -60, -60}, hi[5] = {62, 110, 4, 60, 60}, step[5] = {6, 4, 2, 30, 30};
    std::vector<double> q0 = {42, 100, 3, 0, 0}, q(5);
    int hits = 0, misses = 0;
    for (int i = 0; i < 150; ++i) {
        std::vector<double> q1 = q0;
        for (std::size_t j = 0; j < 5; ++j) q1[j] = std::clamp(q0[j] + step[j] * U(rng), lo[j], hi[j]);
        constexpr int kSamples = 200;
        double least = 1e300;
        for (int s = 0; s <= kSamples; ++s) {
            for (std::size_t j = 0; j < 5; ++j) q[j] = q0[j] + (q1[j] - q0[j]) * s / kSamples;
            least = std::min(least, stage.clearance(q));
        }
        const bool swept = bool(stage.sweep(q0, q1));
        if (least <= 0) CHECK(swept);
        if (swept) CHECK(least < 1.0);
        (swept ? hits : misses)++;
        q0 = q1;
    }
    MESSAGE("chained pieces with a contact: " << hits << ", without: " << misses);
    CHECK(hits > 5);
    CHECK(misses > 50);
}

TEST_CASE("rw2: beads are laid once through the look-back's replay and a refused line") {
    const Machine m = load_with_bodies("rw2");
    const Kinematics k(m);
    // A loop round (110, 110) printed with A following the path: A passes +-168 half way, so
    // the look-back turns the travel move before the loop the other way and prints it again.
    std::string s = "G21\nG90\nM83\nG43.4\n";
    auto tip = [](double a, double z) {
        return "X" + std::to_string(110 + 20 * std::cos(-a * M_PI / 180)) + " Y" + std::to_string(110 + 20 * std::sin(-a * M_PI / 180)) +
               " Z" + std::to_string(z) + " A" + std::to_string(a) + " B30";
    };
    s += "G0 " + tip(0, 5) + " F1200\n";
    double z = 5;
    for (double a = 10; a <= 300; a += 10) {
        if (a == 150) s += "G0 " + tip(a - 10, z += 0.3) + "\n";  // a layer change half way: the look-back's checkpoint
        s += "G1 " + tip(a, z) + " E0.05\n";
    }
    const Outcome direct = run(k, s, CollisionPolicy::Refuse, 0);
    CHECK(direct.error.find("limit") != std::string::npos);  // without look-back: A's limit refuses
    const Outcome held = run(k, s, CollisionPolicy::Refuse, Translator::kDefaultLookback);
    REQUIRE(held.error == "");
    // Every extruding output move with a tip that moves is one bead: count them in the output.
    std::size_t extruding = 0;
    for (const auto& l : lines_of(held.output))
        if (l.rfind("G1 ", 0) == 0 && l.find(" E") != std::string::npos && l.find(" X") != std::string::npos) ++extruding;
    CHECK(held.beads == extruding);
    CHECK(held.beads >= 30);
}

TEST_CASE("a snapshot made from the last one's frames equals one made from nothing") {
    // snap() keeps the chains' frames and, while no rotary turns, every rotation: each snapshot
    // of a sequence that turns, then only moves, then turns again must equal, bit for bit, the
    // snapshot a fresh set of bodies makes at the same joints.
    for (const char* name : {"rw2", "pentarod", "koc5", "core-rtheta"}) {
        CAPTURE(name);
        const Machine m = load_with_bodies(name);
        collision_parts::CollideBodies kept(m);
        std::mt19937 rng(7);
        std::uniform_real_distribution<double> u(-1, 1);
        std::vector<double> q = m.home_joints();
        for (int i = 0; i < 60; ++i) {
            for (std::size_t j = 0; j < q.size(); ++j) {
                const Joint& J = m.joints[j];
                const bool turn = i % 3 == 0;  // two steps in three move the linear joints only
                if (J.rotary && !turn) continue;
                q[j] = 0.5 * (J.min + J.max) + 0.4 * (J.max - J.min) * u(rng);
            }
            collision_parts::Snapshot a, b;
            kept.snap(q.data(), a, true);
            collision_parts::CollideBodies fresh(m);
            fresh.snap(q.data(), b, true);
            for (std::size_t k = 0; k < a.pose.size(); ++k) {
                CHECK(a.pose[k].matrix() == b.pose[k].matrix());
                CHECK(a.centre[k] == b.centre[k]);
                CHECK(a.box[k].min_ == b.box[k].min_);
                CHECK(a.box[k].max_ == b.box[k].max_);
            }
            CHECK(a.tip.matrix() == b.tip.matrix());
            CHECK(a.axis_base == b.axis_base);
            CHECK(a.line_point == b.line_point);
            CHECK(a.line_dir == b.line_dir);
        }
    }
}

TEST_CASE("rw2: filament drawn back is pushed out again before a bead is laid") {
    const Machine m = load_with_bodies("rw2");
    const Kinematics k(m);
    // One printed line, a retraction of 2 mm, a travel, then a move whose E primes: as much
    // as was drawn back lays nothing (it refills the nozzle), more lays a bead of the rest.
    auto beads = [&](const std::string& e_mode, const std::string& retract, const std::string& prime) {
        const std::string s = "G21\nG90\n" + e_mode + "\nG43.4\nG1 X50 Y80 Z0.2 A0 B0 F3000\nG1 X50 Y100 " + retract +
                              "\nG0 X60 Y100\nG1 X60 Y120 " + prime + "\n";
        const Outcome o = run(k, s, CollisionPolicy::Refuse);
        REQUIRE(o.error == "");
        return o.beads;
    };
    CHECK(beads("M83", "E1\nG1 E-2", "E2") == 1);    // the prime only refills
    CHECK(beads("M83", "E1\nG1 E-2", "E2.5") == 2);  // 0.5 mm more: a bead
    CHECK(beads("M83", "E1", "E2") == 2);             // nothing drawn back: every E prints
    // Absolute E, the coordinate reset while retracted: G92 moves the coordinate, not the filament.
    CHECK(beads("M82", "E1\nG1 E-1\nG92 E0", "E2") == 1);
    CHECK(beads("M82", "E1\nG1 E-1\nG92 E0", "E2.5") == 2);
}

TEST_CASE("the bundled examples raise no collision on their machines") {
    const fs::path examples = fs::path(XLATE5_MACHINE_DIR_FOR_TESTS).parent_path() / "examples";
    for (const auto& [machine, file] : std::vector<std::pair<std::string, std::string>>{{"rw2", "rw2_flared_wall.gcode"},
                                                                                          {"pentarod", "pentarod_dome.gcode"},
                                                                                          {"addin4", "addin4_tube.gcode"},
                                                                                          {"wpi5", "wpi5_base.gcode"},
                                                                                          {"wpi5", "wpi5_side.gcode"}}) {
        CAPTURE_BINDING(file);
        const Machine m = load_with_bodies(machine);
        REQUIRE(m.geometry);
        const Kinematics k(m);
        const Outcome o = run(k, test::read(examples / file), CollisionPolicy::Warn, Translator::kDefaultLookback);
        CHECK(o.error == "");
        CHECK(o.found.size() == 0);
        CHECK(o.beads > 20);
    }
}

TEST_CASE("every bundled machine has test bodies that load, with a tool side and a part side") {
    for (const auto& entry : fs::directory_iterator(XLATE5_MACHINE_DIR_FOR_TESTS)) {
        if (entry.path().extension() != ".toml") continue;
        const std::string name = entry.path().stem().string();
        CAPTURE(name);
        const Machine m = load_with_bodies(name);
        REQUIRE(m.geometry);
        bool tool = false, part = false;
        for (const Body& b : m.geometry->bodies) (b.tool_side ? tool : part) = true;
        CHECK(tool);
        CHECK(part);
    }
}

TEST_CASE("wpi5: the tilted-square example dips under its plate, a true contact the check finds") {
    // make_planes.py tilts the square's plane 30 degrees about X through the plate origin: its
    // -Y half lies up to 10 sin 30 = 5 mm under the plate's top, where the nozzle cannot go.
    const fs::path examples = fs::path(XLATE5_MACHINE_DIR_FOR_TESTS).parent_path() / "examples";
    const Machine m = load_with_bodies("wpi5");
    const Kinematics k(m);
    const Outcome o = run(k, test::read(examples / "wpi5_tilted_square.gcode"), CollisionPolicy::Warn, Translator::kDefaultLookback);
    CHECK(o.error == "");
    REQUIRE(!o.found.empty());
    for (const CollisionEvent& e : o.found) {
        CHECK(e.other == "plate");
        CHECK(e.at.z() < 0.01);  // at or under the plate's top (part frame)
    }
}

TEST_CASE("pentarod and koc5: the tilted table against the nozzle's mount is refused; further off passes") {
    // Joint space (G49), so the poses are the machine's own. The table tilted 90 degrees stands
    // up: pentarod's plate (A about X) then faces -Y, between Y 0 and 4 (its thickness) and Z
    // -60..60; koc5's turntable (B about Y) faces +X, between X -5 and 0. The tip 15 mm in front
    // of the plate puts the mount (pentarod: 40 mm deep, so 20 mm either side; koc5's effector:
    // 35 mm radius) through it; 25 mm (pentarod) or 40 mm (koc5) in front keeps it clear.
    struct Case {
        const char* machine;
        std::string setup, hit, miss, body;
    };
    const std::vector<Case> cases = {
        {"pentarod", "G49\nG1 Z80 F1000\nG1 Y-60\nG1 A90\nG1 Z0\n", "G1 Y-15\n", "G1 Y-25\n", "nozzle mount meets print plate"},
        {"koc5", "G49\nG1 Z80 F1000\nG1 X60\nG1 B90\nG1 Z0\n", "G1 X15\n", "G1 X40\n", "effector meets turntable"},
    };
    for (const auto& c : cases) {
        CAPTURE(c.machine);
        const Machine m = load_with_bodies(c.machine);
        const Kinematics k(m);
        const Outcome hit = run(k, c.setup + c.hit);
        CHECK(hit.error.find("in.gcode:6:1: collision: " + c.body) == 0);
        const Outcome miss = run(k, c.setup + c.miss);
        CHECK(miss.error == "");
    }
}

TEST_CASE("s3deformfdm with its authors' meshes: the ring raises no collision; the nozzle driven into the table does" *
          doctest::skip(test::corpus_absent())) {
    // The machine's own meshes (the corpus's cnc_model, Zhang et al.'s S3_DeformFDM repository),
    // in the tip's frame at B = 0 as drawn (the nozzle's tip at the origin, the turntable's top at
    // Z 0): the nozzle and the B carriage ride on the tip (B tilts them), the Z carriage on Z,
    // the C table on the part frame, the frame on the base. The platform mesh is left out: it
    // is drawn Y-up, and where it sits under the table is not known.
    const fs::path meshes = fs::path(test::corpus_dir()) / "s3deformfdm" / "cnc_model";
    auto mesh = [&](const char* name, const char* side, const char* after, const char* file) {
        return std::string("[[bodies]]\nname = \"") + name + "\"\nside = \"" + side + "\"\n" + (*after ? std::string("after = \"") + after + "\"\n" : "") +
               "shape = \"mesh\"\nmesh = \"" + (meshes / file).string() + "\"\n";
    };
    const std::string text = read_machine_file(machine_path("s3deformfdm")) + "\n[collision]\ntip_clearance = 1.0\n" +
                             mesh("nozzle", "tool", "", "cnc_assembly_nozzle.obj") + mesh("B carriage", "tool", "", "cnc_assembly_b_axis.obj") +
                             mesh("Z carriage", "tool", "Z", "cnc_assembly_z_axis.obj") + mesh("C table", "part", "", "cnc_assembly_c_axis.obj") +
                             mesh("frame", "part", "base", "cnc_assembly_frame.obj");
    const Machine m = load_machine_text(text, machine_path("s3deformfdm"));
    REQUIRE(m.geometry->bodies.size() == 5);
    const Kinematics k(m);
    // The ring read back through the machine's own kinematics (as tests/test_pole.cpp does), then
    // translated again with the check. Its first layers only: the whole ring (70,469 lines) costs
    // minutes with the check as it is (docs/limits.md).
    const std::string ring = test::read(meshes.parent_path() / "ring_Gcode.txt");
    TranslatorOptions inv;
    inv.inverse = true;
    inv.extruder_letter = 'A';
    inv.preview_form = OrientationMode::Vector;
    Translator back(k, inv);
    std::string tool;
    std::uint64_t n = 0;
    for (const auto& line : lines_of(ring)) {
        back.feed(line, ++n, tool);
        if (n == 1500) break;
    }
    const Outcome o = run(k, tool, CollisionPolicy::Warn, Translator::kDefaultLookback, OrientationMode::Vector);
    CHECK(o.error == "");
    CHECK(o.found.size() == 0);
    CHECK(o.beads > 500);
    // Lifted clear, over the table beside the ring, then down through the table's top.
    const Outcome hit = run(k, tool + "G1 Z150\nG1 X100 Y0 Z150 I0 J0 K1\nG1 Z-10\n", CollisionPolicy::Refuse, 0, OrientationMode::Vector);
    CHECK(hit.error.find(":1: collision: nozzle meets C table at ") != std::string::npos);
}

TEST_CASE("cli: --collision refuse (the default), warn and off; the report counts what warn found") {
    test::TempDir dir;
    const auto machine = dir.write("rw2-bodies.toml", read_machine_file(machine_path("rw2")) + "\n" +
                                                          test::read(fs::path(XLATE5_MACHINE_DIR_FOR_TESTS).parent_path() / "tests" / "bodies" / "rw2.toml"));
    const std::string wall = rw2_wall();
    const auto in = dir.write("in.gcode", wall + "G1 X38 Y100 Z20 B60\nG1 Z6.2\nG1 X38 Y110 E0.5\n");
    const int line = int(lines_of(wall).size()) + 2;
    auto xlate5 = [&](const std::string& machine_arg, const std::string& args, const std::string& out) {
        const std::string cmd = std::string(XLATE5_BINARY) + " --machine " + test::quote(machine_arg) + " -i " + test::quote(in.string()) + " -o " +
                                test::quote((dir.path / out).string()) + " " + args + " 2>" + test::quote((dir.path / "err").string());
        const int rc = std::system(cmd.c_str());
        return WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
    };
    CHECK(xlate5(machine.string(), "", "refused.gcode") == 1);
    const std::string err = test::read(dir.path / "err");
    CHECK(err.rfind(in.string() + ":" + std::to_string(line) + ":1: collision: heater block meets printed part at line ", 0) == 0);
    CHECK(!fs::exists(dir.path / "refused.gcode"));  // nothing half-written

    CHECK(xlate5(machine.string(), "--collision warn --report " + test::quote((dir.path / "r.json").string()), "warned.gcode") == 0);
    CHECK(test::read(dir.path / "err").find(":" + std::to_string(line) + ": warning: collision: heater block meets printed part") !=
          std::string::npos);
    const std::string report = test::read(dir.path / "r.json");
    CHECK(report.find("\"collisions\": {\"count\": ") != std::string::npos);
    CHECK(report.find("\"collisions\": {\"count\": 0") == std::string::npos);

    // Off, and warned: the output is the translation without bodies, byte for byte.
    CHECK(xlate5(machine.string(), "--collision off", "off.gcode") == 0);
    CHECK(xlate5(machine_path("rw2"), "", "plain.gcode") == 0);
    auto body = [](const std::string& text) { return text.substr(text.find('\n')); };  // the header names the machine file
    CHECK(body(test::read(dir.path / "off.gcode")) == body(test::read(dir.path / "plain.gcode")));
    CHECK(body(test::read(dir.path / "warned.gcode")) == body(test::read(dir.path / "plain.gcode")));
}
