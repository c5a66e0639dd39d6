// SPDX-License-Identifier: GPL-3.0-or-later
// Joint limits and unwinding on rw2 (A within +-168 degrees, cables): a tool azimuth that keeps
// turning would take the continuous solution past +168. Every check is against FK of the
// emitted joints, sampled densely along the firmware's joint-linear moves, and the programmed
// path computed here from the input (never against stored answers).
#include <doctest/doctest.h>

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "helpers.hpp"
#include "translators/error.hpp"
#include "translators/pipeline/joint_limits.hpp"
#include "translators/kinematics/kinematics.hpp"
#include "translators/machine/machine.hpp"
#include "translators/pipeline/translator.hpp"

using namespace xlate5;
using namespace xlate5::test;

namespace {

Machine load(const std::string& name) { return load_machine(std::string(XLATE5_MACHINE_DIR_FOR_TESTS) + "/" + name + ".toml"); }

std::string num(double v, int d = 6) {
    char b[64];
    std::snprintf(b, sizeof b, "%.*f", d, v);
    return b;
}

// One programmed move: tip and angles (A, B) at both ends, and whether it extrudes.
struct Move {
    Eigen::Vector3d tip0, tip1;
    double a0, b0, a1, b1;
    bool prints;
};

// A circle of radius 20 about (110, 110) with the tool leaning 30 degrees out of it: the tip at
// polar angle -A, so A keeps growing as the loop goes round. `travel_at`: the programmed A at
// which a travel move (a lift to the next layer) interrupts the printing; NaN: none.
struct Program {
    std::vector<std::string> lines;  // input, with a ";M<k>" marker before move k
    std::vector<Move> moves;
    std::vector<std::uint64_t> line_of;  // input line number of move k
};

Program azimuth_loop(const Kinematics& k, double a_end, double travel_at, bool vector_form, double a_start = 0) {
    Program p;
    auto tip_at = [](double a, double z) { return Eigen::Vector3d(110 + 20 * std::cos(rad(-a)), 110 + 20 * std::sin(rad(-a)), z); };
    auto add = [&](const std::string& text) { p.lines.push_back(text); };
    add("M83");
    if (vector_form) add("G43.5");
    double a = a_start, z = 5;
    Eigen::Vector3d tip = k.forward(k.machine().home_joints()).tip;  // the placing move starts at home
    auto words = [&](double aa, const Eigen::Vector3d& t) {
        std::string s = " X" + num(t.x()) + " Y" + num(t.y()) + " Z" + num(t.z());
        if (vector_form) {
            std::vector<double> q(5, 0.0);
            q[3] = aa, q[4] = 30;
            const Eigen::Vector3d u = k.forward(q).axis;
            s += " I" + num(u.x(), 9) + " J" + num(u.y(), 9) + " K" + num(u.z(), 9);
        } else {
            s += " A" + num(aa, 3) + " B30";
        }
        return s;
    };
    auto move = [&](double a1, double z1, bool prints, const char* g) {
        const Eigen::Vector3d t1 = tip_at(a1, z1);
        p.moves.push_back({tip, t1, a, 30, a1, 30, prints});
        add(";M" + std::to_string(p.moves.size() - 1));
        p.line_of.push_back(p.lines.size() + 1);
        add(std::string(g) + words(a1, t1) + (prints ? " E0.05" : "") + (p.moves.size() == 1 ? " F1200" : ""));
        tip = t1, a = a1, z = z1;
    };
    move(a, z, false, "G0");  // place the tool (a travel move)
    while (a < a_end - 1e-9) {
        const double next = std::min(a + 5, a_end);
        if (!std::isnan(travel_at) && std::abs(a - travel_at) < 1e-9) move(a, z + 0.3, false, "G0");  // layer change
        move(next, z, true, "G1");
    }
    return p;
}

struct Verdict {
    double worst_tip = 0;          // mm, any move
    double worst_print_axis = 0;   // degrees, printing moves: FK axis against the programmed one
    double worst_print_excess = 0; // degrees a printing move turns a rotary beyond its programmed turn
    double worst_limit_excess = 0; // degrees (or mm) beyond any limit
    int unwinds = 0;               // travel moves that ended off the programmed angles
    bool negative_b_printed = false;
};

// Walks the output: every joint-linear move, sampled through FK, against the input move whose
// marker it follows.
Verdict check(const Machine& m, const Kinematics& k, const Program& p, const std::string& out, bool vector_form) {
    Verdict v;
    std::vector<double> q = m.home_joints();
    int current = -1;
    std::vector<double> start_of_move = q;
    std::vector<double> travel(5, 0.0);
    auto finish_move = [&]() {
        if (current < 0) return;
        const Move& mv = p.moves[std::size_t(current)];
        if (mv.prints) {
            v.worst_print_excess = std::max(v.worst_print_excess, travel[3] - std::abs(mv.a1 - mv.a0));
            v.worst_print_excess = std::max(v.worst_print_excess, travel[4] - std::abs(mv.b1 - mv.b0));
        } else if (current > 0) {
            // The travel move's end: the programmed orientation, on whatever solution.
            std::vector<double> prog(5, 0.0);
            prog[3] = mv.a1, prog[4] = mv.b1;
            CHECK(angle_deg(k.forward(q).axis, k.forward(prog).axis) < 0.01);
            if (std::abs(q[3] - mv.a1) > 1e-3 || std::abs(q[4] - mv.b1) > 1e-3) ++v.unwinds;
        }
    };
    for (const auto& line : lines_of(out)) {
        if (line.rfind(";M", 0) == 0) {
            finish_move();
            current = std::stoi(line.substr(2));
            start_of_move = q;
            travel.assign(5, 0.0);
            continue;
        }
        if (line.rfind("G1 ", 0) != 0 && line.rfind("G0 ", 0) != 0) continue;
        REQUIRE(current >= 0);
        const Move& mv = p.moves[std::size_t(current)];
        std::vector<double> cur = q;
        const auto w = words_of(line);
        for (std::size_t j = 0; j < m.joints.size(); ++j)
            if (w.count(m.joints[j].output)) cur[j] = w.at(m.joints[j].output);
        for (std::size_t j = 0; j < m.joints.size(); ++j) {
            v.worst_limit_excess = std::max({v.worst_limit_excess, cur[j] - m.joints[j].max, m.joints[j].min - cur[j]});
            travel[j] += std::abs(cur[j] - q[j]);
        }
        if (mv.prints && cur[4] < 0) v.negative_b_printed = true;
        for (int s = 1; s <= 60; ++s) {
            std::vector<double> qq(cur.size());
            for (std::size_t j = 0; j < qq.size(); ++j) qq[j] = q[j] + (cur[j] - q[j]) * s / 60.0;
            const Pose fk = k.forward(qq);
            v.worst_tip = std::max(v.worst_tip, seg_dist(fk.tip, mv.tip0, mv.tip1));
            if (!mv.prints) continue;
            // The programmed axis at the same place along the move.
            const Eigen::Vector3d d = mv.tip1 - mv.tip0;
            const double t = std::clamp((fk.tip - mv.tip0).dot(d) / d.squaredNorm(), 0.0, 1.0);
            std::vector<double> prog(5, 0.0), p0(5, 0.0), p1(5, 0.0);
            prog[3] = mv.a0 + t * (mv.a1 - mv.a0), prog[4] = mv.b0 + t * (mv.b1 - mv.b0);
            p0[3] = mv.a0, p0[4] = mv.b0, p1[3] = mv.a1, p1[4] = mv.b1;
            Eigen::Vector3d want = k.forward(prog).axis;
            if (vector_form) {  // G43.5: the great circle between the ends
                const Eigen::Vector3d u0 = k.forward(p0).axis, u1 = k.forward(p1).axis;
                const double ang = std::acos(std::clamp(u0.dot(u1), -1.0, 1.0));
                want = ang < 1e-12 ? u0 : ((std::sin((1 - t) * ang) * u0 + std::sin(t * ang) * u1) / std::sin(ang)).normalized();
            }
            v.worst_print_axis = std::max(v.worst_print_axis, angle_deg(fk.axis, want));
        }
        q = cur;
    }
    finish_move();
    return v;
}

std::string run(Translator& t, const Program& p) {
    std::string out;
    for (std::size_t i = 0; i < p.lines.size(); ++i) t.feed(p.lines[i], i + 1, out);
    t.finish(out);
    return out;
}

// Printing joints to 3 decimals moves the tip by up to about this much.
constexpr double kPrintSlack = 0.0035;

// Where and why translating `p` stops (line 0 and no message when it does not).
struct Failure {
    std::uint64_t line = 0;
    std::string message;
};
Failure failure_of(Translator& t, const Program& p) {
    try {
        run(t, p);
    } catch (const InputError& e) {
        return {e.line(), e.message()};
    }
    return {};
}

}  // namespace

TEST_CASE("limits: a layer change before the crossing unwinds A there (other branch, B < 0); the printing stays continuous") {
    const Machine m = load("rw2");
    const Kinematics k(m);
    REQUIRE(k.has_flip());
    for (const bool vector_form : {false, true}) {
        CAPTURE(vector_form);
        // Print A 0 -> 150, change layer, print A 150 -> 300: the continuous solution would
        // pass +168 twenty degrees after the layer change.
        const Program p = azimuth_loop(k, 300, 150, vector_form);
        TranslatorOptions o;
        Translator t(k, o);
        t.set_lookback(Translator::kDefaultLookback);
        std::string out;
        REQUIRE_NOTHROW(out = run(t, p));
        const Verdict v = check(m, k, p, out, vector_form);
        MESSAGE((vector_form ? "G43.5" : "G43.4") << ": worst tip deviation " << v.worst_tip << " mm, printed axis "
                                                 << v.worst_print_axis << " deg, unwinds " << v.unwinds);
        CHECK(v.worst_limit_excess <= 1e-9);
        CHECK(v.worst_tip <= m.motion.tolerance + kPrintSlack);
        CHECK(v.worst_print_axis <= (vector_form ? m.motion.angle_tolerance : 0.0) + 0.05);
        // No printing move turns a rotary more than programmed (G43.5: B follows the great
        // circle, a few hundredths of a degree off the programmed tilt).
        CHECK(v.worst_print_excess <= (vector_form ? 0.1 : 2e-3));
        CHECK(v.unwinds == 1);                // the layer change, and only it
        CHECK(v.negative_b_printed);          // the second layer is printed on the B < 0 branch
    }
}

TEST_CASE("limits: without a travel move before the crossing, a clear error names the line") {
    const Machine m = load("rw2");
    const Kinematics k(m);
    for (const bool vector_form : {false, true}) {
        CAPTURE(vector_form);
        const Program p = azimuth_loop(k, 300, std::nan(""), vector_form);
        Translator t(k, {});
        t.set_lookback(Translator::kDefaultLookback);
        const auto [failed, message] = failure_of(t, p);
        MESSAGE(message);
        // The first move whose programmed A passes 168.
        std::uint64_t expected = 0;
        for (std::size_t i = 0; i < p.moves.size() && !expected; ++i)
            if (p.moves[i].a1 > 168) expected = p.line_of[i];
        CHECK(failed == expected);
        CHECK(contains(message, "joint A"));
        CHECK(contains(message, "168.000"));
        CHECK(contains(message, "limits"));
        CHECK(contains(message, "travel move"));
    }
}

TEST_CASE("limits: a linear joint past its travel is told as placement (the slicer's origin), not as a turn back") {
    const Machine m = load("rw2");
    const Kinematics k(m);
    // rw2's X runs -30 .. 250; a part sliced for a 300 mm bed lies partly beyond it. A rotary
    // past its limit (A over 168, printed with no travel move before) keeps the turning advice.
    Program linear;
    linear.lines = {"G1 X100 Y100 Z1 A0 B0 F600", "G1 X200 Y100 Z1 A0 B0 E1", "G1 X290 Y100 Z1 A0 B0 E2"};
    Program rotary;
    rotary.lines = {"G1 X100 Y100 Z1 A0 B30 F600", "G1 X101 Y100 Z1 A120 B30 E1", "G1 X102 Y100 Z1 A175 B30 E2"};
    for (const std::size_t lookback : {std::size_t(0), Translator::kDefaultLookback}) {
        CAPTURE(lookback);
        Translator t(k, {});
        t.set_lookback(lookback);
        const auto [line, message] = failure_of(t, linear);
        CAPTURE_BINDING(message);
        CHECK(line == 3);
        CHECK(contains(message, "joint X would go to"));
        CHECK(contains(message, "-30.000 .. 250.000"));
        CHECK(contains(message, "outside the machine's travel"));
        CHECK(contains(message, "slicer's origin"));
        CHECK(contains(message, "Place the part"));
        CHECK_FALSE(contains(message, "travel move (G0"));
        CHECK_FALSE(contains(message, "turn the joint back"));
        Translator r(k, {});
        r.set_lookback(lookback);
        const auto [rline, rmessage] = failure_of(r, rotary);
        CAPTURE_BINDING(rmessage);
        CHECK(rline == 3);
        CHECK(contains(rmessage, "joint A"));
        CHECK(contains(rmessage, "turn"));
        CHECK_FALSE(contains(rmessage, "slicer's origin"));
    }
}

TEST_CASE("limits: the look-back window is bounded: a travel move too far back does not help") {
    const Machine m = load("rw2");
    const Kinematics k(m);
    // The layer change at A = 50: 24 moves (and markers) before the crossing.
    const Program p = azimuth_loop(k, 300, 50, false, 0);
    Translator t(k, {});
    t.set_lookback(10);
    const auto [failed, message] = failure_of(t, p);
    CHECK(failed > 0);
    CHECK(contains(message, "within the 10 lines"));
    // With a window that reaches it, the same program translates, within the limits.
    Translator wide(k, {});
    wide.set_lookback(200);
    std::string out;
    REQUIRE_NOTHROW(out = run(wide, p));
    const Verdict v = check(m, k, p, out, false);
    CHECK(v.worst_limit_excess <= 1e-9);
    CHECK(v.worst_tip <= m.motion.tolerance + kPrintSlack);
    CHECK(v.unwinds == 1);
}

TEST_CASE("limits: fewer end solutions tried by the look-back: the nearest one still unwinds; at least one is always tried") {
    const Machine m = load("rw2");
    const Kinematics k(m);
    const Program p = azimuth_loop(k, 300, 150, false);
    Translator all(k, {});
    all.set_lookback(Translator::kDefaultLookback);
    std::string expected;
    REQUIRE_NOTHROW(expected = run(all, p));
    REQUIRE(check(m, k, p, expected, false).unwinds == 1);
    // The layer change unwinds onto the nearest other solution (the other branch): one tried is
    // enough, and a bound below one is one.
    for (const int candidates : {1, 0, -5}) {
        CAPTURE(candidates);
        Translator t(k, {});
        t.set_lookback(Translator::kDefaultLookback, candidates);
        std::string out;
        REQUIRE_NOTHROW(out = run(t, p));
        CHECK(out == expected);
    }
}

TEST_CASE("limits: a travel move whose end is outside the limits takes the other branch by itself") {
    const Machine m = load("rw2");
    const Kinematics k(m);
    // No look-back: the travel move at A = 150 -> 200 (programmed) ends past +168 itself.
    Program p = azimuth_loop(k, 150, std::nan(""), false);
    Move travel{p.moves.back().tip1, {}, 150, 30, 200, 30, false};
    travel.tip1 = Eigen::Vector3d(110 + 20 * std::cos(rad(-200.0)), 110 + 20 * std::sin(rad(-200.0)), 5.3);
    p.moves.push_back(travel);
    p.lines.push_back(";M" + std::to_string(p.moves.size() - 1));
    p.lines.push_back("G0 X" + num(travel.tip1.x()) + " Y" + num(travel.tip1.y()) + " Z5.3 A200 B30");
    // Then printing on from there, programmed A 200 -> 260 (joints: the flipped image).
    for (double a = 200; a < 260; a += 5) {
        Move mv{p.moves.back().tip1, {}, a, 30, a + 5, 30, true};
        mv.tip1 = Eigen::Vector3d(110 + 20 * std::cos(rad(-(a + 5))), 110 + 20 * std::sin(rad(-(a + 5))), 5.3);
        p.moves.push_back(mv);
        p.lines.push_back(";M" + std::to_string(p.moves.size() - 1));
        p.lines.push_back("G1 X" + num(mv.tip1.x()) + " Y" + num(mv.tip1.y()) + " Z5.3 A" + num(a + 5, 3) + " B30 E0.05");
    }
    Translator t(k, {});
    std::string out;
    for (std::size_t i = 0; i < p.lines.size(); ++i) REQUIRE_NOTHROW(t.feed(p.lines[i], i + 1, out));
    const Verdict v = check(m, k, p, out, false);
    CHECK(v.worst_limit_excess <= 1e-9);
    CHECK(v.worst_tip <= m.motion.tolerance + kPrintSlack);
    CHECK(v.worst_print_axis <= 0.05);
    CHECK(v.worst_print_excess <= 2e-3);
    CHECK(v.unwinds == 1);
    CHECK(v.negative_b_printed);
    // G91 after the unwind: a relative A is a programmed angle, carried through the same image.
    const std::vector<double> before = t.joints();
    out.clear();
    t.feed("G91", 100, out);
    t.feed("G1 A5 E0.05", 101, out);
    std::vector<double> prog(5, 0.0), now(5, 0.0);
    prog[3] = 265, prog[4] = 30;
    now[3] = t.joints()[3], now[4] = t.joints()[4];
    CHECK(angle_deg(k.forward(prog).axis, k.forward(now).axis) < 1e-6);
    CHECK(std::abs(t.joints()[3] - before[3]) == doctest::Approx(5).epsilon(1e-9));
}

TEST_CASE("limits: without any limit trouble the look-back changes nothing in the output") {
    const Machine m = load("rw2");
    const Kinematics k(m);
    const Program p = azimuth_loop(k, 160, 80, false);
    Translator direct(k, {}), held(k, {});
    held.set_lookback(Translator::kDefaultLookback);
    std::string a, b;
    for (std::size_t i = 0; i < p.lines.size(); ++i) direct.feed(p.lines[i], i + 1, a);
    b = run(held, p);
    CHECK(a == b);
}

TEST_CASE("limits: where a machine claims the flip, FK agrees: (t1 + 180, -t2) gives the same tool axis") {
    int machines_with_flip = 0;
    for (const std::string name : {"rw2", "pentarod", "koc5", "wpi5", "xyzac-trt", "addin4"}) {
        CAPTURE(name);
        const Machine m = load(name);
        const Kinematics k(m);
        if (!k.has_flip()) continue;
        ++machines_with_flip;
        const auto& rot = k.rotary_joints();
        REQUIRE(rot.size() == 2);
        std::vector<double> q = m.home_joints(), f = q;
        double worst = 0;
        for (int i = 0; i < 200; ++i) {
            q[std::size_t(rot[0])] = -180 + 1.7 * i;
            q[std::size_t(rot[1])] = -90 + 0.83 * i;
            f = q;
            f[std::size_t(rot[0])] += 180;
            f[std::size_t(rot[1])] = -q[std::size_t(rot[1])];
            worst = std::max(worst, angle_deg(k.forward(q).axis, k.forward(f).axis));
        }
        CHECK(worst < 1e-9);
    }
    CHECK(machines_with_flip >= 2);  // rw2's head and the A/C tables at least
}

TEST_CASE("limits: within_limits and LimitBox give check_limits's verdict, at the limits, past them, on the slack's edge and on NaN") {
    for (const char* name : {"rw2", "pentarod", "wpi5"}) {
        CAPTURE(name);
        const Machine m = load(name);
        const LimitBox box(m);
        std::vector<double> q(m.joints.size());
        int differ = 0, outside = 0;
        for (int i = 0; i < 20000; ++i) {
            for (std::size_t j = 0; j < q.size(); ++j) {
                const Joint& J = m.joints[j];
                const double lo = J.bounded() ? J.min : -720, hi = J.bounded() ? J.max : 720;
                const int pick = (i + int(j) * 7) % 11;
                // Mostly inside; some exactly at a limit, just past its slack, or NaN.
                q[j] = pick == 0 ? lo : pick == 1 ? hi : pick == 2 ? hi + 2e-9 : pick == 3 ? lo - 2e-9
                     : pick == 4 && i % 5 == 0 ? std::nan("") : lo + (hi - lo) * double((i * 37 + int(j) * 13) % 1000) / 999.0;
            }
            // Some joint on the edge of its slack, or a double either side of it.
            if (i % 3 == 0) {
                const std::size_t j = std::size_t(i / 3) % q.size();
                const double slack = 1e-9;  // kLimitSlack (constants.hpp's kPi would clash with this file's)
                const double edge = i % 2 ? m.joints[j].max + slack : m.joints[j].min - slack;
                q[j] = i % 9 == 0 ? edge : std::nextafter(edge, i % 9 == 3 ? 1e300 : -1e300);
            }
            const bool fast = within_limits(m, q);
            outside += !fast;
            if (fast != check_limits(m, q).ok()) ++differ;
            if (box.contains(q) != fast) ++differ;
        }
        CHECK(differ == 0);
        CHECK(outside > 0);
    }
}
