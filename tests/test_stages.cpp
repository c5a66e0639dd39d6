// SPDX-License-Identifier: GPL-3.0-or-later
// The stages the front door wires together, each driven on its own: arcs -> chords (against the
// circle through RS274's centre rules), the compensation stage (against interpolation done here),
// the limit policy (every answer checked through FK and the machine's limits), and command
// reading and line plans (the words each command takes).
#include <doctest/doctest.h>

#include <cmath>
#include <cstring>
#include <random>
#include <span>
#include <string>
#include <vector>

#include "helpers.hpp"
#include "translators/pipeline/arcs.hpp"
#include "translators/pipeline/compensation.hpp"
#include "translators/pipeline/feed_rules.hpp"
#include "translators/pipeline/joint_limits.hpp"
#include "translators/error.hpp"
#include "translators/inputs/gcode_lexer.hpp"
#include "translators/kinematics/kinematics.hpp"
#include "translators/pipeline/line_commands.hpp"
#include "translators/machine/machine.hpp"
#include "translators/pipeline/planner.hpp"

using namespace xlate5;
using namespace xlate5::test;

namespace {

Machine load(const std::string& name) { return load_machine(std::string(XLATE5_MACHINE_DIR_FOR_TESTS) + "/" + name + ".toml"); }

// Signed angle (radians) from u to v in the plane, counter-clockwise positive.
double turn(const Eigen::Vector2d& u, const Eigen::Vector2d& v) { return std::atan2(u.x() * v.y() - u.y() * v.x(), u.dot(v)); }

}  // namespace

TEST_CASE("arcs: every chord end on the circle, within the tolerance, turning the right way, ending exactly at the end") {
    std::mt19937 rng(17);
    std::uniform_real_distribution<double> U(-1, 1);
    int checked = 0;
    for (int plane : {17, 18, 19}) {
        const ArcPlane pl = arc_plane(plane);
        for (int i = 0; i < 200; ++i) {
            Arc a;
            a.plane = plane;
            a.clockwise = i % 2 == 0;
            a.turns = i % 7 == 0 ? 2 : 1;
            a.start = Eigen::Vector3d(50 * U(rng), 50 * U(rng), 50 * U(rng));
            const double r = 1 + 30 * std::abs(U(rng));
            // The centre from the start (I J K form); the end on the circle, helical along the normal.
            const Eigen::Vector2d c(a.start[pl.a] + r * std::cos(3 * U(rng)), a.start[pl.b] + r * std::sin(3 * U(rng)));
            a.offset_a = c.x() - a.start[pl.a];
            a.offset_b = c.y() - a.start[pl.b];
            const double r0 = std::hypot(a.offset_a, a.offset_b);
            const double phi = 3.1 * U(rng);
            a.end = a.start;
            a.end[pl.a] = c.x() + r0 * std::cos(std::atan2(-a.offset_b, -a.offset_a) + phi);
            a.end[pl.b] = c.y() + r0 * std::sin(std::atan2(-a.offset_b, -a.offset_a) + phi);
            a.end[pl.n] += 5 * U(rng);
            const double tol = 0.005;
            std::vector<Eigen::Vector3d> ends;
            REQUIRE(arc_chords(a, tol, ends).empty());
            REQUIRE(!ends.empty());
            CHECK(ends.back() == a.end);
            // The whole sweep: the short way round in the arc's sense, plus the extra turns.
            const Eigen::Vector2d s(a.start[pl.a] - c.x(), a.start[pl.b] - c.y()), e(a.end[pl.a] - c.x(), a.end[pl.b] - c.y());
            double expect = turn(s, e) * (a.clockwise ? -1 : 1);
            if (expect <= 1e-12) expect += 2 * kPi;
            expect += 2 * kPi * (a.turns - 1);
            // From the start round the centre in the arc's sense, through every chord end.
            Eigen::Vector2d prev = s;
            double swept = 0, worst_sagitta = 0;
            for (std::size_t k = 0; k < ends.size(); ++k) {
                const Eigen::Vector2d p(ends[k][pl.a] - c.x(), ends[k][pl.b] - c.y());
                CHECK(std::abs(p.norm() - r0) < 1e-9);
                const double step = turn(prev, p) * (a.clockwise ? -1 : 1);
                CHECK(step > 0);
                swept += step;
                worst_sagitta = std::max(worst_sagitta, r0 * (1 - std::cos(step / 2)));
                // Helical: the normal coordinate moves in proportion to the angle.
                CHECK(std::abs(ends[k][pl.n] - (a.start[pl.n] + (a.end[pl.n] - a.start[pl.n]) * swept / expect)) < 1e-9);
                prev = p;
            }
            CHECK(worst_sagitta <= tol * (1 + 1e-9));
            CHECK(std::abs(swept - expect) < 1e-9);
            // No more chords than the tolerance needs: one fewer would leave it.
            if (ends.size() > 1) CHECK(r0 * (1 - std::cos(expect / double(ends.size() - 1) / 2)) > tol * (1 - 1e-9));
            ++checked;
        }
    }
    CHECK(checked == 600);
}

TEST_CASE("arcs: R gives the centre RS274 puts it at, the shorter arc for R > 0 and the longer for R < 0") {
    for (const bool clockwise : {true, false}) {
        for (const double R : {10.0, -10.0}) {
            CAPTURE(clockwise);
            CAPTURE(R);
            Arc a;
            a.clockwise = clockwise;
            a.by_radius = true;
            a.radius = R;
            a.start = Eigen::Vector3d(0, 0, 0);
            a.end = Eigen::Vector3d(12, 0, 0);
            std::vector<Eigen::Vector3d> ends;
            REQUIRE(arc_chords(a, 0.01, ends).empty());
            // The centre lies on the chord's bisector x = 6, 8 from it (a 6-8-10 triangle), on
            // one side or the other; every chord end is on that circle, and going round it the
            // arc turns clockwise for G2 and counter-clockwise for G3.
            const Eigen::Vector2d first(ends.front().x(), ends.front().y());
            const Eigen::Vector2d c = std::abs((first - Eigen::Vector2d(6, 8)).norm() - 10) < 1e-9 ? Eigen::Vector2d(6, 8) : Eigen::Vector2d(6, -8);
            Eigen::Vector2d prev2 = Eigen::Vector2d(0, 0) - c;
            for (const auto& p : ends) {
                const Eigen::Vector2d v = Eigen::Vector2d(p.x(), p.y()) - c;
                CHECK(std::abs(v.norm() - 10) < 1e-9);
                CHECK(turn(prev2, v) * (clockwise ? -1 : 1) > 0);
                prev2 = v;
            }
            // Shorter arc: 2 asin(6/10) of the circle; longer: the rest.
            const double short_arc = 2 * std::asin(0.6), long_arc = 2 * kPi - 2 * std::asin(0.6);
            double swept = 0;
            Eigen::Vector2d from = Eigen::Vector2d(0, 0) - c;
            for (const auto& p : ends) {
                const Eigen::Vector2d v = Eigen::Vector2d(p.x(), p.y()) - c;
                swept += std::abs(turn(from, v));
                from = v;
            }
            CHECK(std::abs(swept - (R > 0 ? short_arc : long_arc)) < 1e-9);
        }
    }
    Arc bad;
    bad.by_radius = true;
    bad.radius = 5;
    bad.end = Eigen::Vector3d(12, 0, 0);
    std::vector<Eigen::Vector3d> ends;
    CHECK(contains(arc_chords(bad, 0.01, ends), "too small"));
    Arc off;
    off.offset_a = 5;
    off.end = Eigen::Vector3d(20, 0, 0);
    CHECK(contains(arc_chords(off, 0.01, ends), "not on its circle"));
}

TEST_CASE("compensation stage: nominal joints in, the table's error taken off, or why not") {
    Compensation comp;
    comp.source = "test table";
    CompensationTerm t;
    t.joint = 0;
    t.by = 3;
    t.angle = {-90, 0, 90};
    t.error = {1.0, 2.0, 4.0};
    comp.terms.push_back(t);
    CompensationStage stage(comp);
    for (const double a : {-90.0, -45.0, 0.0, 30.0, 90.0}) {
        const std::vector<double> q = {10, 20, 30, a, 0};
        const auto r = stage.apply(q);
        REQUIRE(r.ok());
        // Linear between the points, as the table is read.
        const double e = a <= 0 ? 1.0 + (a + 90) / 90 : 2.0 + 2.0 * a / 90;
        CHECK(r.sent[0] == doctest::Approx(10 - e).epsilon(1e-12));
        CHECK(r.sent[1] == 20);
        CHECK(r.sent[3] == a);
        CHECK(q[0] == 10);  // the nominal joints are not touched
    }
    const auto out = stage.apply(std::vector<double>{10, 20, 30, 100, 0});
    CHECK_FALSE(out.ok());
    CHECK(contains(out.why(), "test table"));
    CHECK(contains(out.why(), "-90.000 .. 90.000"));
    // Nothing to correct: the joints go on as they are.
    const Compensation none;
    CompensationStage pass(none);
    const std::vector<double> q = {1, 2, 3, 4, 5};
    const auto r = pass.apply(q);
    CHECK(r.ok());
    CHECK(r.sent.data() == q.data());  // the same memory: nothing copied
    CHECK(r.sent.size() == q.size());
}

TEST_CASE("limit policy: within the limits, on a branch, or continuous whatever the limits, each reaching the axis") {
    const Machine m = load("rw2");  // A within +-168: the continuous solution can leave it
    const Kinematics k(m);
    const int A = m.joint_index('A'), B = m.joint_index('B');
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> U(-1, 1);
    int outside_continuous = 0;
    for (int i = 0; i < 300; ++i) {
        std::vector<double> prev = m.home_joints();
        prev[std::size_t(A)] = 168 * U(rng);
        prev[std::size_t(B)] = 60 * U(rng);
        std::vector<double> q = prev;
        q[std::size_t(A)] = prev[std::size_t(A)] + 40 * U(rng);
        q[std::size_t(B)] = 5 + 55 * std::abs(U(rng));
        const Eigen::Vector3d axis = k.forward(q).axis;
        std::vector<double> within = prev, cont = prev, b0 = prev, b1 = prev;
        const auto sols = k.orientation_solutions(axis);
        const auto& rot = k.rotary_joints();
        const auto rw = orient_within_limits(m, rot, sols, prev, prev, within);
        REQUIRE(orient_continuous(m, rot, sols, prev, cont).ok());
        CHECK((k.forward(cont).axis - axis).norm() < 1e-9);
        if (!inside_limits(m.joints[std::size_t(A)], cont[std::size_t(A)])) ++outside_continuous;
        if (rw.ok()) {
            CHECK((k.forward(within).axis - axis).norm() < 1e-9);
            CHECK(check_limits(m, within).ok());
        } else {
            CHECK(rw.status == IkStatus::OutOfLimits);
        }
        // The two branches: (A, B) and (A + 180, -B), both reaching the axis where inside the limits.
        const bool ok0 = orient_on_branch(m, rot, sols, 0, prev, prev, b0).ok(), ok1 = orient_on_branch(m, rot, sols, 1, prev, prev, b1).ok();
        if (ok0) CHECK((k.forward(b0).axis - axis).norm() < 1e-9);
        if (ok1) CHECK((k.forward(b1).axis - axis).norm() < 1e-9);
        if (ok0 && ok1) CHECK(std::abs(b0[std::size_t(B)] + b1[std::size_t(B)]) < 1e-9);
        CHECK(orient_on_branch(m, rot, sols, 2, prev, prev, b0).status == IkStatus::Unreachable);
    }
    CHECK(outside_continuous > 0);  // the case the planner's policy is for did occur
}

TEST_CASE("limit policy: the shortcut for two rotaries and two solutions chooses what the general path chooses, bit for bit") {
    // Previous angles near, at and past the limits, far round an unbounded joint (wrap180's path
    // past 360 degrees), half a turn away, NaN; axes at random and on a pole (a free joint).
    int checked = 0, failed = 0;
    for (const char* name : {"pentarod", "rw2", "koc5", "xyzac-trt", "wpi5", "addin4"}) {
        const Machine m = load(name);
        const Kinematics k(m);
        const auto& rot = k.rotary_joints();
        if (rot.size() != 2) continue;
        std::mt19937 rng(11);
        std::uniform_real_distribution<double> U(-1, 1);
        for (int i = 0; i < 20000; ++i) {
            std::vector<double> prev = m.home_joints();
            for (int r : rot) {
                const Joint& J = m.joints[std::size_t(r)];
                double v;
                switch (i % 6) {
                    case 0: v = J.bounded() ? J.min + (J.max - J.min) * (0.5 + 0.5 * U(rng)) : 200 * U(rng); break;
                    case 1: v = (U(rng) < 0 ? J.min : J.max) + 1e-9 * U(rng) * (i % 5); break;  // at a limit (unbounded: huge)
                    case 2: v = 1e5 * U(rng); break;                                               // many turns round
                    case 3: v = 180.0 * std::round(4 * U(rng)) + (i % 4 == 3 ? 1e-12 * U(rng) : 0.0); break;  // half turns
                    case 4: v = (J.bounded() ? J.max : 360.0) + 30 * U(rng); break;
                    default: v = i % 97 == 0 ? std::nan("") : 720 * U(rng); break;
                }
                prev[std::size_t(r)] = v;
            }
            const Eigen::Vector3d axis = i % 50 == 0 ? Eigen::Vector3d::UnitZ() : Eigen::Vector3d(U(rng), U(rng), U(rng));
            auto sols = k.orientation_solutions(axis);
            if (i % 3 == 0) {  // made by hand on a coarse grid: ties between the two, free joints
                sols.count = 2;
                for (auto& row : sols.angle)
                    for (double& v : row) v = i % 89 == 0 && U(rng) < 0 ? std::nan("") : 10.0 * std::round(19 * U(rng));
                if (i / 3 % 2 == 1) sols.angle[1][0] = -sols.angle[0][0], sols.angle[1][1] = -sols.angle[0][1];
            }
            std::vector<double> free = prev;
            for (double& v : free) v += 1.5;
            std::vector<double> a = prev, b = prev;
            const IkResult ra = orient_within_limits(m, rot, sols, prev, free, a);
            const IkResult rb = orient_within_limits_general(m, rot, sols, prev, free, b);
            REQUIRE(ra.status == rb.status);
            CHECK(ra.message == rb.message);
            REQUIRE(a.size() == b.size());
            CHECK(std::memcmp(a.data(), b.data(), a.size() * sizeof(double)) == 0);
            ++checked;
            failed += !ra.ok();
        }
    }
    CHECK(checked >= 40000);
    CHECK(failed > 0);
}

namespace {

// The params read, as "X1 E2" (letters and whole values).
std::string params_of(const LineCommands& c) {
    std::string out;
    for (const Param& p : c.params) {
        if (!out.empty()) out += ' ';
        out += p.letter;
        out += std::to_string(int(p.value));
    }
    return out;
}

}  // namespace

TEST_CASE("command reading: the params are the words after the commands, as written, or rewritten where they must be") {
    Block b;
    LineCommands c;
    // The common line: the params are the block's own words.
    lex_line("G1 X1 Y2 E3", b);
    read_commands(b, 'E', c);
    REQUIRE(c.count == 1);
    CHECK(c.params.data() == b.words().data() + 1);
    CHECK(params_of(c) == "X1 Y2 E3");
    CHECK(c.letters == (letter_bit('X') | letter_bit('Y') | letter_bit('E')));
    // A command after a word: the words keep their order around it.
    lex_line("X1 G1 Y2 M3 S5", b);
    read_commands(b, 'E', c);
    CHECK(c.count == 2);
    CHECK(params_of(c) == "X1 Y2 S5");
    CHECK(c.params[0].column == 1);
    CHECK(c.params[2].column == 13);
    // The extrusion letter read as E, wherever it is; E itself then refused.
    lex_line("G1 X1 A2 Y3", b);
    read_commands(b, 'A', c);
    CHECK(params_of(c) == "X1 E2 Y3");
    CHECK(c.params[1].column == 7);
    CHECK(c.params[1].text == "2");
    CHECK(b.words()[2].letter == 'A');  // the block's word is left as it was
    lex_line("G1 X1 E2", b);
    CHECK_THROWS_AS(read_commands(b, 'A', c), LineError);
    // G43.4 H: the register word is dropped.
    lex_line("G43.4 H1 G1 X2", b);
    read_commands(b, 'E', c);
    CHECK(params_of(c) == "X2");
    // M104's T names a tool: a param, not a command.
    lex_line("M104 T1 S200", b);
    read_commands(b, 'E', c);
    CHECK(c.count == 1);
    CHECK(params_of(c) == "T1 S200");
    CHECK(c.params.data() == b.words().data() + 1);
    // A word twice, counted after the extrusion letter is read as E.
    lex_line("G1 X1 Y2 X3", b);
    try {
        read_commands(b, 'E', c);
        FAIL("no error");
    } catch (const LineError& e) {
        CHECK(e.column() == 10);
    }
    lex_line("G1 A1 E2", b);
    CHECK_THROWS_AS(read_commands(b, 'A', c), LineError);
}

TEST_CASE("command reading: the block's letter set gives what reading word by word gives") {
    // read_commands takes the common line from Block::letters; with every letter in that set
    // (M among them) it reads word by word whatever the words. Both readings of each line,
    // on random lines of G M T H and axis letters (a word twice, a command after a word, flags,
    // codes with a second decimal), with E and A as the extrusion letter.
    auto reading = [](const Block& b, char extruder) {
        LineCommands c;
        std::string text;
        try {
            read_commands(b, extruder, c);
        } catch (const LineError& e) {
            return "error " + std::to_string(e.column()) + " " + e.what();
        }
        for (std::size_t i = 0; i < c.count; ++i)
            text += std::string(1, c.commands[i].letter) + std::to_string(c.commands[i].code10) + "@" + std::to_string(c.commands[i].column) + " ";
        text += "|";
        for (const Param& p : c.params) {
            text += ' ';
            text += p.letter;
            text += p.text;
            text += '@' + std::to_string(p.column) + (p.has_value ? "" : "!");
        }
        text += " | " + std::to_string(c.letters) + (c.has_owner ? " owner" : "");
        return text;
    };
    std::mt19937 rng(5);
    const std::string letters = "GGGGXYZEFABMTHSIJKN";
    const char* codes[] = {"0", "1", "2", "17", "28", "43.4", "90", "92", "1.55", "104", "3"};
    int fast = 0;
    for (int n = 0; n < 20000; ++n) {
        std::string line;
        const int words = int(rng() % 6);
        for (int k = 0; k < words; ++k) {
            const char letter = letters[rng() % letters.size()];
            line += letter;
            if (letter == 'G' || letter == 'M' || letter == 'T') line += codes[rng() % std::size(codes)];
            else if (rng() % 8 != 0 || letter == 'N') line += std::to_string(int(rng() % 200) - 100) + ".5";
            line += ' ';
        }
        Block b;
        try {
            lex_line(line, b);
        } catch (const LineError&) {
            continue;
        }
        std::uint32_t set = 0;
        bool twice = false;
        for (const Word& w : b.words()) {
            twice = twice || (set & letter_bit(w.letter));
            set |= letter_bit(w.letter);
        }
        REQUIRE(b.letters == set);
        for (const char extruder : {'E', 'A'}) {
            const std::string by_set = reading(b, extruder);
            Block by_word = b;
            by_word.letters = letter_bit('Z') * 2 - 1;
            CHECK_MESSAGE(by_set == reading(by_word, extruder), line << " (extrusion letter " << extruder << ")");
            fast += !twice && extruder == 'E';
        }
    }
    CHECK(fast > 2000);
}

TEST_CASE("line plan: a motion command takes the line's words as they are; S, or no motion command, plans otherwise") {
    Block b;
    LineCommands c;
    LinePlan plan;
    auto planned = [&](const char* line, int motion) {
        lex_line(line, b);
        read_commands(b, 'E', c);
        plan_line(c, motion, "XYZIJKEFAB", "XYZAB", plan);
    };
    planned("G1 X1 Y2 F300", -1);
    REQUIRE(plan.count == 1);
    CHECK(plan.steps[0].command.code10 == 10);
    CHECK(plan.steps[0].verbatim);
    CHECK(plan.steps[0].words.data() == c.params.data());
    CHECK(plan.steps[0].words.size() == 3);
    // No motion command: the modal motion takes the words, not verbatim; none in effect is an error.
    planned("X1 Y2", 0);
    REQUIRE(plan.count == 1);
    CHECK(plan.steps[0].command.code10 == 0);
    CHECK_FALSE(plan.steps[0].verbatim);
    CHECK(plan.steps[0].words.size() == 2);
    CHECK_THROWS_AS(planned("X1 Y2", -1), LineError);
    // S with a move: the move keeps its words and S goes on a line of its own.
    planned("G1 X1 S200", -1);
    REQUIRE(plan.count == 2);
    CHECK(plan.steps[0].command.letter == 'S');
    CHECK(plan.steps[0].words.size() == 1);
    CHECK(plan.steps[1].command.code10 == 10);
    REQUIRE(plan.steps[1].words.size() == 1);
    CHECK(plan.steps[1].words[0].letter == 'X');
    // S alone is passed on as written.
    planned("S100", 1);
    REQUIRE(plan.count == 1);
    CHECK(plan.steps[0].command.letter == 'S');
    CHECK(plan.steps[0].verbatim);
}

TEST_CASE("planner state: PlannerState's copy gives what vector assignment gives, bit for bit") {
    std::mt19937_64 rng(15);
    auto random_joints = [&](std::size_t n) {
        std::vector<double> v(n);
        for (double& x : v) {
            std::uint64_t bits = rng();
            std::memcpy(&x, &bits, sizeof x);  // any bits: signed zeros, NaNs, infinities
        }
        return v;
    };
    auto same_bits = [](const std::vector<double>& a, const std::vector<double>& b) {
        return a.size() == b.size() && (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(double)) == 0);
    };
    for (int round = 0; round < 2000; ++round) {
        const std::size_t n_to = rng() % 12, n_from = round % 3 == 0 ? rng() % 12 : n_to;  // mostly equal sizes
        const std::vector<double> from = random_joints(n_from);
        PlannerState a, b;
        a.q = random_joints(n_to);
        b.q = from;
        b.pose.tip = Eigen::Vector3d(1, 2, double(round));
        b.pose.axis = Eigen::Vector3d(0, 1, 0);
        b.tip_known = round % 2 == 0;
        b.image.sign[1] = -1;
        b.image.shift[0] = 360.0 * round;
        b.rezeroed[0] = 720;
        b.rezeroed[1] = -double(round);
        a = b;
        REQUIRE(same_bits(a.q, b.q));
        CHECK(a.pose.tip == b.pose.tip);
        CHECK(a.pose.axis == b.pose.axis);
        CHECK(a.tip_known == b.tip_known);
        CHECK(a.image == b.image);
        CHECK(a.rezeroed[0] == b.rezeroed[0]);
        CHECK(a.rezeroed[1] == b.rezeroed[1]);
    }
}

// The planner writes no text: a G49 move, a G92 and a travel move's re-zero come back as values
// (translator.cpp writes them), with the state moved on as the command says. koc5: an unbounded
// C re-zeroed past 1800 degrees.
TEST_CASE("planner: a joint move, a G92 and a re-zero come back as values, the state moved on") {
    const Machine m = load("koc5");
    const Kinematics kin(m);
    PlannerState state;
    state.q = m.home_joints();
    state.pose = kin.forward(state.q);
    Planner planner(kin, state, nullptr);
    const std::size_t b = 3, c = 4;
    const std::vector<double> home = state.q;

    cmd::JointMove jm;
    jm.gcode = 1;
    jm.q[b] = 10;
    jm.q[c] = 30;
    jm.given = (1u << b) | (1u << c);
    JointStep step = planner.joint_move(jm);
    CHECK(step.gcode == 1);
    CHECK(step.given == jm.given);
    for (std::size_t j = 0; j < home.size(); ++j) {
        CHECK(state.q[j] == (j == b ? 10.0 : j == c ? 30.0 : home[j]));
        CHECK(step.q[j] == state.q[j]);
    }
    CHECK((state.pose.tip - kin.forward(state.q).tip).norm() < 1e-12);
    jm.relative = true;
    jm.q[b] = 5;
    jm.given = 1u << b;
    step = planner.joint_move(jm);
    CHECK(state.q[b] == 15.0);
    CHECK(step.q[b] == 15.0);
    jm.relative = false;
    jm.q[b] = 100;  // past B's 90
    CHECK_THROWS_AS(planner.joint_move(jm), LineError);
    CHECK(state.q[b] == 15.0);

    cmd::SetPosition set;
    set.q[b] = 0;
    set.q[c] = 1790;
    set.which = (1u << b) | (1u << c);
    set.pose_from_joints = true;
    const SetJoints told = planner.set_position(set);
    CHECK(told.which == set.which);
    CHECK(!told.e);
    CHECK(told.q[b] == 0.0);
    CHECK(told.q[c] == 1790.0);
    CHECK(state.q[c] == 1790.0);
    CHECK((state.pose.tip - kin.forward(state.q).tip).norm() < 1e-12);

    // G43.4 travel to C 1900 (the tip where it is, on the C axis): past 1800, re-zeroed by whole
    // turns on arrival; the program's next angle is read in the re-zeroed frame.
    ToolMove mv;
    mv.gcode = 0;
    mv.mode = OrientationMode::Angles;
    mv.any_xyz = true;
    mv.tip = state.pose.tip;
    mv.any_rotary = true;
    mv.angles[b] = 0;
    mv.angles[c] = 1900;
    mv.commanded = 1u << c;
    mv.feed = 1000;
    LineRun run;
    run.line_no = 1;
    const MovePlan& p = planner.plan(mv, run);
    CHECK(p.travel);
    CHECK(p.move.q1[c] == doctest::Approx(1900));
    REQUIRE(planner.arrive(p, MotionOutcome{}, false, run));
    const std::span<const SetJoints> g92s = planner.arrived(p, nullptr, run);
    REQUIRE(g92s.size() == 1);
    CHECK(g92s[0].which == 1u << c);
    CHECK(g92s[0].q[c] == doctest::Approx(1900 - 5 * 360.0));
    CHECK(state.q[c] == g92s[0].q[c]);
    mv.angles[c] = 1910;
    const PassedNumber e{1.0, "1", 0};  // a printing move: never re-zeroed
    mv.e = e;
    const MovePlan& printing = planner.plan(mv, run);
    CHECK(printing.prints);
    CHECK(printing.move.q1[c] == doctest::Approx(1910 - 5 * 360.0));
    CHECK_FALSE(planner.arrive(printing, MotionOutcome{}, false, run));
    CHECK(state.q[c] == doctest::Approx(1910 - 5 * 360.0));
}

// Each firmware's length of a move, from the rules as their documentation states them (NIST
// RS274NGC 2.5.2.1 for Marlin and RepRapFirmware; Marlin's ARTICULATED_ROBOT_ARM; Klipper's
// toolhead for a move without X Y Z), on X Y Z A B with every joint's move chosen by hand.
TEST_CASE("feed rules: each firmware measures a move its own way") {
    const JointKinds kinds{{0, 1, 2}, {3, 4}};
    const double q0[5] = {1, 2, 3, 10, 20};
    const double tilt[5] = {4, 6, 3, 20, 20};     // X 3, Y 4 (5 mm) and A 10 degrees
    const double turn[5] = {1, 2, 3, 20, 0};      // A 10, B -20 degrees, no linear move
    CHECK(nist_length(q0, tilt, kinds, 0) == doctest::Approx(5));
    CHECK(marlin_articulated_length(q0, tilt, kinds, 0) == doctest::Approx(std::sqrt(25.0 + 100.0)));
    CHECK(klipper_length(q0, tilt, kinds, 0) == doctest::Approx(5));
    CHECK(nist_length(q0, turn, kinds, 0) == doctest::Approx(std::sqrt(500.0)));
    CHECK(marlin_articulated_length(q0, turn, kinds, 0) == doctest::Approx(std::sqrt(500.0)));
    CHECK(klipper_length(q0, turn, kinds, 0) == doctest::Approx(20));
    CHECK(klipper_length(q0, turn, kinds, 30) == doctest::Approx(30));  // E counts when larger
    CHECK(klipper_length(q0, tilt, kinds, 30) == doctest::Approx(5));   // not with X Y Z moving
    CHECK((length_rule(FirmwareDialect::RepRap) == &nist_length));
    CHECK((length_rule(FirmwareDialect::Klipper) == &klipper_length));
    CHECK((length_rule(FirmwareDialect::MarlinArticulated) == &marlin_articulated_length));
}
