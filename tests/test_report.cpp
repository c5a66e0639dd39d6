// SPDX-License-Identifier: GPL-3.0-or-later
// The kinematic-error report: agrees with an independent dense check, stays bounded in size.
#include <doctest/doctest.h>

#include <cmath>
#include <limits>
#include <sstream>
#include <utility>
#include <string>

#include "helpers.hpp"
#include "translators/error.hpp"
#include "translators/kinematics/kinematics.hpp"
#include "translators/machine/machine.hpp"
#include "translators/inspect/preflight.hpp"
#include "translators/inspect/report.hpp"
#include "translators/pipeline/translator.hpp"

using namespace xlate5;
using namespace xlate5::test;

namespace {

double field(const std::string& json, const std::string& object, const std::string& key) {
    const auto o = json.find("\"" + object + "\"");
    REQUIRE(o != std::string::npos);
    if (key.empty()) return std::stod(json.substr(o + object.size() + 4));  // "object": value
    const auto k = json.find("\"" + key + "\": ", o);
    REQUIRE(k != std::string::npos);
    return std::stod(json.substr(k + key.size() + 4));
}

}  // namespace

TEST_CASE("the report's worst tip deviation is what dense FK sampling of the output finds") {
    const std::vector<std::string> in = {"G1 X100 Y100 Z10 A0 B0 F1200", "G1 X110 Y100 A40 B20", "G1 X120 Y110 A-20 B35",
                                         "G1 X100 Y120 A10 B0", "G1 X100 Y100"};
    for (const bool segment : {false, true}) {
        CAPTURE(segment);
        Machine m = load_machine(std::string(XLATE5_MACHINE_DIR_FOR_TESTS) + "/rw2.toml");
        m.motion.segment = segment;
        const Kinematics k(m);
        DeviationReport report("t.gcode", "rw2", m.motion.tolerance, m.motion.angle_tolerance);
        TranslatorOptions o;
        o.report = &report;
        Translator t(k, o);
        // Independent: each input move's programmed segment against 400 FK samples along every
        // printed joint line it became.
        std::vector<double> fw = t.joints();
        double worst = 0;
        std::uint64_t n = 0;
        for (const auto& line : in) {
            const Pose a = t.pose();
            std::string out;
            t.feed(line, ++n, out);
            const Pose b = t.pose();
            for (const auto& l : lines_of(out)) {
                if (l.rfind("G1", 0) != 0) continue;
                std::vector<double> q = fw;
                const auto w = words_of(l);
                for (std::size_t j = 0; j < q.size(); ++j)
                    if (w.count(m.joints[j].output)) q[j] = w.at(m.joints[j].output);
                for (int s = 1; s < 400; ++s) {
                    std::vector<double> qq(q.size());
                    for (std::size_t j = 0; j < q.size(); ++j) qq[j] = fw[j] + (q[j] - fw[j]) * s / 400.0;
                    const Eigen::Vector3d p = k.forward(qq).tip, ab = b.tip - a.tip;
                    const double tt = ab.squaredNorm() > 0 ? std::clamp((p - a.tip).dot(ab) / ab.squaredNorm(), 0.0, 1.0) : 0.0;
                    worst = std::max(worst, (a.tip + tt * ab - p).norm());
                }
                fw = q;
            }
        }
        const std::string json = report.json();
        const double reported = field(json, "tip_deviation_mm", "max");
        MESSAGE("segment " << segment << ": reported " << reported << " mm, dense check " << worst << " mm");
        // The report samples the unrounded pieces; the dense check the printed ones (3 decimals).
        CHECK(std::abs(reported - worst) <= 0.02 * worst + 0.003);
        if (segment) CHECK(reported <= m.motion.tolerance);
        else CHECK(reported > 10 * m.motion.tolerance);
        CHECK(field(json, "tip_deviation_mm", "moves") == 5);
    }
}

TEST_CASE("report memory is bounded: a million moves, a plot of at most 2000 points") {
    DeviationReport r("big.gcode", "rw2", 0.01, 0.5);
    for (std::uint64_t i = 1; i <= 1000000; ++i) r.add_move(i, 0.005 + 0.004 * std::sin(double(i) * 1e-4), 0.1, 1e-4, 1 + int(i % 3 == 0));
    const std::string svg = r.svg();
    std::size_t points = 0;
    const auto poly = svg.find("<polyline");
    REQUIRE(poly != std::string::npos);
    for (std::size_t at = svg.find(',', poly); at != std::string::npos; at = svg.find(',', at + 1)) ++points;
    CHECK(points <= 2000);
    CHECK(points >= 500);
    CHECK(r.max_tip() == doctest::Approx(0.009).epsilon(1e-3));
    const std::string json = r.json();
    CHECK(field(json, "tip_deviation_mm", "p50") == doctest::Approx(0.005).epsilon(0.3));
    CHECK(field(json, "tip_deviation_mm", "moves") == 1000000);
    CHECK(json.find("\"moves_split\": 333333") != std::string::npos);
}

TEST_CASE("an infinite or NaN deviation counts in the top bin and the JSON and SVG hold only numbers") {
    // Degenerate geometry can make a deviation infinite: its bin index was a cast of infinity.
    const double inf = std::numeric_limits<double>::infinity(), nan = std::numeric_limits<double>::quiet_NaN();
    DeviationReport r("t.gcode", "rw2", 0.01, 0.5);
    r.add_move(1, 0.001, 0, 0, 1);
    r.add_move(2, inf, nan, inf, 1);
    r.add_move(3, 0.002, 0, 0, 1);
    const std::string json = r.json();
    CAPTURE(json);
    CHECK(json.find("inf") == std::string::npos);
    CHECK(json.find("nan") == std::string::npos);
    CHECK(contains(json, "\"max\": 1e999, \"max_at_line\": 2"));
    // Two of three moves are small; the 99th percentile is the infinite one, in the top bin (1e3 mm).
    CHECK(field(json, "tip_deviation_mm", "p99") == doctest::Approx(1000));
    CHECK(field(json, "tip_deviation_mm", "p50") < 0.01);
    const std::string svg = r.svg();
    CHECK(svg.find("inf") == std::string::npos);
    CHECK(svg.find("nan") == std::string::npos);
}

TEST_CASE("the tolerance holds for the joints as printed, and the report measures those (bundled examples)") {
    // The output is rounded to the dialect's decimals; the firmware follows the rounded joints.
    // Independent: parse the output text, run each printed joint line through FK densely, and
    // measure it against the input move's programmed segment (the pose before and after it).
    const std::string examples = std::string(XLATE5_MACHINE_DIR_FOR_TESTS) + "/../examples/";
    for (const auto& [file_name, name] : {std::pair<const char*, const char*>{"rw2_flared_wall.gcode", "rw2"}, {"pentarod_dome.gcode", "pentarod"}}) {
        const std::string file = file_name;
        CAPTURE(file);
        const Machine m = load_machine(std::string(XLATE5_MACHINE_DIR_FOR_TESTS) + "/" + name + ".toml");
        const Kinematics k(m);
        DeviationReport report(file, name, m.motion.tolerance, m.motion.angle_tolerance);
        TranslatorOptions o;
        o.report = &report;
        Translator t(k, o);
        std::istringstream in(read(examples + file));
        std::string line;
        std::uint64_t n = 0;
        std::vector<double> fw = m.home_joints();
        double worst_dense = 0, at_reported_line = -1;
        bool placed = false;
        while (std::getline(in, line)) {
            const Pose a = t.pose();
            std::string out;
            t.feed(line, ++n, out);
            const Pose b = t.pose();
            double dense = 0, sampled = 0;  // 400 points per piece; the report's 14 interior points
            for (const auto& l : lines_of(out)) {
                const auto w = words_of(l.substr(0, l.find(';')));
                if (!w.count('G')) continue;
                const double g = w.at('G');
                if (g == 28) fw = m.home_joints();
                if (g != 0 && g != 1 && g != 92) continue;
                std::vector<double> q = fw;
                for (std::size_t j = 0; j < q.size(); ++j)
                    if (w.count(m.joints[j].output)) q[j] = w.at(m.joints[j].output);
                if (g == 92) {
                    fw = q;
                    continue;
                }
                auto deviation = [&](double s) {
                    std::vector<double> qq(q.size());
                    for (std::size_t j = 0; j < q.size(); ++j) qq[j] = fw[j] + (q[j] - fw[j]) * s;
                    const Eigen::Vector3d p = k.forward(qq).tip, ab = b.tip - a.tip;
                    const double tt = ab.squaredNorm() > 0 ? std::clamp((p - a.tip).dot(ab) / ab.squaredNorm(), 0.0, 1.0) : 0.0;
                    return (a.tip + tt * ab - p).norm();
                };
                for (int s = 1; s < 400; ++s) dense = std::max(dense, deviation(s / 400.0));
                for (int s = 1; s <= 14; ++s) sampled = std::max(sampled, deviation(s / 15.0));
                fw = q;
            }
            // Before the program places the tip, moves are joint moves (no tool-space path).
            if (placed) worst_dense = std::max(worst_dense, dense);
            placed = placed || t.pose().tip != a.tip;
            if (n == report.worst_tip_line()) at_reported_line = sampled;
        }
        MESSAGE(file << ": report max " << report.max_tip() << " mm at line " << report.worst_tip_line() << ", printed path (dense) "
                     << worst_dense << " mm, tolerance " << m.motion.tolerance);
        CHECK(worst_dense <= m.motion.tolerance);
        CHECK(report.max_tip() <= m.motion.tolerance);
        CHECK(report.max_tip() > 0.5 * m.motion.tolerance);  // the split works near the tolerance
        // The report's figure is the printed path's, at its own sample points.
        CHECK(std::abs(report.max_tip() - at_reported_line) <= 1e-9);
    }
}

namespace {

// Joint values after each output line of `out` (G0/G1 only), starting from `q`.
std::vector<std::vector<double>> joints_along(const Machine& m, std::vector<double> q, const std::string& out) {
    std::vector<std::vector<double>> r;
    for (const auto& l : lines_of(out)) {
        if (l.rfind("G1", 0) != 0 && l.rfind("G0", 0) != 0) continue;
        const auto w = words_of(l);
        for (std::size_t j = 0; j < q.size(); ++j)
            if (w.count(m.joints[j].output)) q[j] = w.at(m.joints[j].output);
        r.push_back(q);
    }
    return r;
}

}  // namespace

TEST_CASE("the report's joint ranges are the extremes of the written joints, its time the moves' lengths over their feeds") {
    Machine m = load_machine(std::string(XLATE5_MACHINE_DIR_FOR_TESTS) + "/pentarod.toml");
    // The linear joints' speed limits left out (pentarod's Z, 180 mm/min, would slow these moves):
    // the time below is the tip's, and the rotaries' limits where they bind.
    for (Joint& j : m.joints)
        if (!j.rotary) j.max_feed = 0;
    const Kinematics k(m);
    DeviationReport report("t.gcode", "pentarod", m.motion.tolerance, m.motion.angle_tolerance);
    TranslatorOptions o;
    o.report = &report;
    o.start_mode = OrientationMode::Angles;
    Translator t(k, o);
    const std::vector<double> home = t.joints();
    std::string out;
    std::uint64_t n = 0;
    for (const char* line : {"G1 X10 Y0 Z5 A0 C0 F600", "G1 X20 Y10 Z5", "G1 A30", "G1 X0 Y0 Z5 F1200", "G1 C-50", "G1 X-15 Y5 Z2"})
        t.feed(line, ++n, out);
    t.finish(out);
    const std::string json = report.json();
    CAPTURE(json);
    // Independent: extremes over the start and every written line (printed to 3 decimals).
    std::vector<double> lo = home, hi = home;
    for (const auto& q : joints_along(m, home, out))
        for (std::size_t j = 0; j < q.size(); ++j) lo[j] = std::min(lo[j], q[j]), hi[j] = std::max(hi[j], q[j]);
    for (std::size_t j = 0; j < m.joints.size(); ++j) {
        CAPTURE(m.joints[j].name);
        CHECK(std::abs(field(json, std::string(1, m.joints[j].name) + "\": {", "min") - lo[j]) <= 1e-3);
        CHECK(std::abs(field(json, std::string(1, m.joints[j].name) + "\": {", "max") - hi[j]) <= 1e-3);
    }
    CHECK(hi[3] == doctest::Approx(30));  // A reached 30 and C -50: the ranges are not the home's
    CHECK(lo[4] == doctest::Approx(-50));
    // Time: tip length over the feed; a pure turn at the rotary's max_feed (A 1800, C 3600 deg/min),
    // or the machine's rotary_feed when that is slower.
    const double turn_a = std::max(30.0 / m.joints[3].max_feed, 30.0 / m.motion.rotary_feed);
    const double turn_c = std::max(50.0 / m.joints[4].max_feed, 50.0 / m.motion.rotary_feed);
    const double minutes = std::sqrt(125.0) / 600 + std::sqrt(200.0) / 600 + turn_a + std::sqrt(500.0) / 1200 + turn_c +
                           std::sqrt(15.0 * 15 + 5 * 5 + 3 * 3) / 1200;
    CHECK(field(json, "estimated_minutes", "") == doctest::Approx(minutes).epsilon(1e-4));
    CHECK(field(json, "unwinds", "") == 0);
    CHECK(field(json, "branch_changes", "") == 0);
}

TEST_CASE("the report counts a travel move that takes the other orientation branch at a limit") {
    Machine m = load_machine(std::string(XLATE5_MACHINE_DIR_FOR_TESTS) + "/rw2.toml");
    const Kinematics k(m);
    DeviationReport report("t.gcode", "rw2", m.motion.tolerance, m.motion.angle_tolerance);
    TranslatorOptions o;
    o.report = &report;
    Translator t(k, o);
    const std::vector<double> home = t.joints();
    std::string out;
    std::uint64_t n = 0;
    // A175 is past rw2's A limit (168): the travel ends on A-5 B-20, the same tool axis (eq. 4.5).
    for (const char* line : {"G1 X100 Y100 Z10 A150 B20 F1200", "G1 X110 Y100 Z10 A175 B20", "G1 X120 Y100 Z10 A170 B20"}) t.feed(line, ++n, out);
    t.finish(out);
    const auto q = joints_along(m, home, out);
    REQUIRE(!q.empty());
    // Independent of the planner: count the sign changes of B between written lines.
    int flips = 0, sign = 0;
    for (const auto& qi : q) {
        if (std::abs(qi[4]) <= 1) continue;  // passing upright
        const int s = qi[4] > 0 ? 1 : -1;
        flips += sign != 0 && s != sign;
        sign = s;
    }
    const std::string json = report.json();
    CAPTURE(out);
    CAPTURE(json);
    CHECK(q.back()[4] == doctest::Approx(-20));
    CHECK(flips == 1);
    CHECK(field(json, "branch_changes", "") == flips);
    CHECK(field(json, "unwinds", "") == 0);
}

TEST_CASE("the plot's deviation axis is logarithmic with decade ticks written plainly, its line axis in round steps") {
    DeviationReport r("t.gcode", "rw2", 0.01, 0.5);
    for (std::uint64_t i = 1; i <= 1000; ++i) r.add_move(i, i <= 500 ? 0.001 : 0.1, 0, 0, 1);
    const std::string svg = r.svg();
    CAPTURE(svg);
    // label -> y of each tick
    auto ticks = [&](const std::string& cls) {
        std::map<std::string, double> t;
        for (std::size_t at = svg.find("class=\"" + cls + "\""); at != std::string::npos; at = svg.find("class=\"" + cls + "\"", at + 1)) {
            const auto gt = svg.find('>', at), end = svg.find('<', gt);
            const auto ya = svg.find(cls == "ytick" ? "y=\"" : "x=\"", at) + 3;
            t[svg.substr(gt + 1, end - gt - 1)] = std::stod(svg.substr(ya));
        }
        return t;
    };
    const auto y = ticks("ytick");
    REQUIRE(y.count("0.001"));
    REQUIRE(y.count("0.01"));
    REQUIRE(y.count("0.1"));
    // Equal spacing per decade: a log scale.
    CHECK(std::abs((y.at("0.001") - y.at("0.01")) - (y.at("0.01") - y.at("0.1"))) < 1e-6);
    CHECK(y.at("0.001") > y.at("0.1"));  // up is larger
    // The points of 0.1 mm sit on the 0.1 tick (labels are drawn 4 below their line).
    const auto poly = svg.find("points=\"");
    const auto last_point = svg.rfind(',', svg.find('"', poly + 8));
    CHECK(std::stod(svg.substr(last_point + 1)) == doctest::Approx(y.at("0.1") - 4));
    const auto x = ticks("xtick");
    CHECK(x.size() >= 4);
    CHECK(x.size() <= 12);
    for (const auto& [label, pos] : x) {
        const double v = std::stod(label);
        const double m = v / std::pow(10.0, std::floor(std::log10(v)));  // leading digits: multiples of 1, 2 or 5 steps
        CAPTURE_BINDING(label);
        CHECK((std::abs(m - std::round(m)) < 1e-9));
        CHECK(label.find('e') == std::string::npos);
    }
}

TEST_CASE("the report counts every G92 that re-zeroes a wound-up turntable, the joint move before the tip is placed included") {
    // koc5's C re-zeroes beyond 1800 degrees at the end of a travel move. Under G43.4, after G28,
    // a C-only move is a joint move (the tip is not placed yet), which the report does not
    // measure; its re-zero is still one.
    for (const std::size_t lookback : {std::size_t(0), Translator::kDefaultLookback}) {
        CAPTURE(lookback);
        Machine m = load_machine(std::string(XLATE5_MACHINE_DIR_FOR_TESTS) + "/koc5.toml");
        const Kinematics k(m);
        DeviationReport report("t.gcode", "koc5", m.motion.tolerance, m.motion.angle_tolerance);
        TranslatorOptions o;
        o.report = &report;
        o.start_mode = OrientationMode::Angles;
        Translator t(k, o);
        t.set_lookback(lookback);
        std::string out;
        std::uint64_t n = 0;
        // The program's angles keep counting across a re-zero (2010: 10 degrees on from 2000).
        for (const char* line : {"G28", "G1 C2000 F1000", "G1 X0 Y0 Z10 C2010", "G1 X5 Y0 Z10 C4060", "G1 X5 Y5 Z10 C4060 E1"}) t.feed(line, ++n, out);
        t.finish(out);
        CAPTURE(out);
        // Independent: the G92 lines naming C in the output, and the move lines before each.
        int written = 0;
        std::uint64_t moves = 0;
        std::vector<std::uint64_t> after;
        for (const auto& l : lines_of(out)) {
            if (l.rfind("G0 ", 0) == 0 || l.rfind("G1 ", 0) == 0) ++moves;
            if (l.rfind("G92 ", 0) == 0 && words_of(l).count('C')) ++written, after.push_back(moves);
        }
        CHECK(written == 2);
        CHECK(field(report.json(), "rezeros", "") == written);
        std::vector<std::uint64_t> marked;
        for (const auto& mk : report.marks())
            if (mk.kind == DeviationReport::MarkKind::Rezero) marked.push_back(mk.moves_written);
        CHECK(marked == after);
    }
}

namespace {

// A program on rw2 (angles mode) with a report, its blank lines the places of refused lines:
// with `with_refused`, the i-th blank is fed refused[i % size], which must be refused naming
// joint A; without, a blank is skipped. What the callers compare: the output, the report (its
// JSON, its plot and its marks' count), the joints and G90/G91 at the end.
struct RefusedRun {
    std::string out, report;
    std::vector<double> joints;
    bool absolute = false;
};

RefusedRun run_with_refused(const Machine& m, const Kinematics& k, std::size_t lookback, const std::vector<std::string>& program,
                            const std::vector<std::string>& refused, bool with_refused) {
    DeviationReport report("t.gcode", "rw2", m.motion.tolerance, m.motion.angle_tolerance);
    TranslatorOptions o;
    o.report = &report;
    o.start_mode = OrientationMode::Angles;
    Translator t(k, o);
    t.set_lookback(lookback);
    RefusedRun r;
    std::uint64_t n = 0;
    int threw = 0, blanks = 0;
    for (const auto& line : program) {
        ++n;
        if (!line.empty()) {
            t.feed(line, n, r.out);
        } else if (with_refused) {
            try {
                t.feed(refused[std::size_t(blanks) % refused.size()], n, r.out);
            } catch (const InputError& e) {
                ++threw;
                CAPTURE(e.message());
                CHECK(contains(e.message(), "joint A"));
            }
        }
        blanks += line.empty();
    }
    t.finish(r.out);
    CHECK(threw == (with_refused ? blanks : 0));
    r.report = report.json() + report.svg() + std::to_string(report.marks().size());
    r.joints = t.joints();
    r.absolute = t.modes().absolute;
    return r;
}

}  // namespace

TEST_CASE("a refused line's moves leave the report as its output leaves the file (an arc cut short at a limit), with the look-back or not") {
    // rw2's A stops at +-168. An arc under G43.4 turning A from 100 on is refused at the chord that
    // passes 168, after the chords before it were measured. A caller that carries on after the
    // error (the service) gets the output and the report of the program without that line.
    Machine m = load_machine(std::string(XLATE5_MACHINE_DIR_FOR_TESTS) + "/rw2.toml");
    REQUIRE(m.joints[std::size_t(m.joint_index('A'))].max == 168);
    const Kinematics k(m);
    for (const std::size_t lookback : {std::size_t(0), Translator::kDefaultLookback})
    for (const bool travel_before : {false, true}) {
        CAPTURE(lookback);
        CAPTURE(travel_before);
        std::vector<std::string> program = {"M83", "G1 X110 Y100 Z10 A0 B30 E0.1 F1200", "G1 X115 Y100 Z10 A100 B30 E0.1", "",
                                            "G1 X120 Y100 Z10 A120 B30 E0.1", "G1 X120 Y105 Z10 A110 B30 E0.1"};
        std::string refused = "G2 X125 Y100 I5 J0 A200 E1";  // refused: nothing to unwind on before it
        if (travel_before) {
            // Turned back on the travel move, the printing from there still passes a limit.
            program[2] = "G0 X115 Y100 Z10 A100 B30";
            refused = "G2 X125 Y100 I5 J0 A520 E1";  // 420 degrees of printing: no solution keeps it within 336
        }
        const RefusedRun with = run_with_refused(m, k, lookback, program, {refused}, true);
        const RefusedRun without = run_with_refused(m, k, lookback, program, {refused}, false);
        // Without the look-back what the firmware was told of the refused line is not known
        // (interpreter.cpp): the next line is written with every joint.
        if (lookback > 0) CHECK(with.out == without.out);
        else CHECK(with.out.size() > without.out.size());
        CHECK(with.report == without.report);
    }
}

TEST_CASE("a refused printing line is undone by replaying the lines before it: output and report as without it") {
    // A printing line that fails keeps no copy of the state (only a line that may travel does):
    // the look-back takes the state back to its window's start and runs the window's commands
    // again, quietly. Refused lines before the window (no travel yet), inside it before and after
    // the replay that turns the loop's travel move the other way, and at the end: the output and
    // the report are those of the program without them, with the look-back or not.
    Machine m = load_machine(std::string(XLATE5_MACHINE_DIR_FOR_TESTS) + "/rw2.toml");
    const Kinematics k(m);
    auto tip = [](double a, double z) {
        return "X" + std::to_string(110 + 20 * std::cos(-a * M_PI / 180)) + " Y" + std::to_string(110 + 20 * std::sin(-a * M_PI / 180)) +
               " Z" + std::to_string(z) + " A" + std::to_string(a) + " B30";
    };
    // Printing moves past A's limit (+-168) from wherever the tip is, and one whose mode (G91)
    // the interpreter has changed before the move fails.
    const std::vector<std::string> refused = {"G1 A600 E0.05", "G91 G1 A700 E0.05", "G1 A-600 E0.05"};
    for (const std::size_t lookback : {std::size_t(0), Translator::kDefaultLookback}) {
        CAPTURE(lookback);
        // Without the look-back the loop stops short of A's limit.
        std::vector<std::string> program = {"M83", "G1 " + tip(0, 5) + " E0.05 F1200", "", "G1 " + tip(5, 5) + " E0.05", "",
                                            "G0 " + tip(5, 5.3)};
        double z = 5.3;
        for (double a = 10; a <= (lookback ? 300 : 160); a += 10) {
            if (a == 150) program.push_back("G0 " + tip(a - 10, z += 0.3));  // the window the replay turns
            program.push_back("G1 " + tip(a, z) + " E0.05");
            if (a == 100 || a == 160 || a == 200 || a == 300) program.push_back("");
        }
        const RefusedRun with = run_with_refused(m, k, lookback, program, refused, true);
        const RefusedRun without = run_with_refused(m, k, lookback, program, refused, false);
        CHECK(with.absolute);
        CHECK(without.absolute);
        CHECK(with.report == without.report);
        CHECK(with.joints == without.joints);
        // Without the look-back what the firmware was told of a refused line is not known: the
        // next line is written with every joint.
        if (lookback > 0) CHECK(with.out == without.out);
        else CHECK(with.out.size() > without.out.size());
    }
}

TEST_CASE("the plot's title escapes the file name by XML's rules: an '&' or a crafted name stays text") {
    // The SVG is XML: '&' must be '&amp;', '<' must be '&lt;'. A name that closes the <text>
    // and opens an element of its own must come out as text, not as an element.
    const std::string name = "a&b </text><script>alert(1)</script><text>.gcode";
    DeviationReport r(name, "rw2", 0.01, 0.5);
    r.add_move(1, 0.001, 0, 0, 1);
    const std::string svg = r.svg();
    CAPTURE(svg);
    CHECK(svg.find("<script") == std::string::npos);
    CHECK(contains(svg, "a&amp;b &lt;/text&gt;&lt;script&gt;alert(1)&lt;/script&gt;&lt;text&gt;.gcode on rw2"));
    // Every '&' starts an entity XML knows.
    for (std::size_t at = svg.find('&'); at != std::string::npos; at = svg.find('&', at + 1)) {
        const std::string rest = svg.substr(at, 6);
        CHECK((rest.rfind("&amp;", 0) == 0 || rest.rfind("&lt;", 0) == 0 || rest.rfind("&gt;", 0) == 0 ||
               rest.rfind("&quot;", 0) == 0 || rest.rfind("&apos;", 0) == 0));
    }
}

TEST_CASE("preflight: a lone move takes its trapezoid; short moves over a slow link drain the planner, a fast link keeps it fed") {
    using namespace xlate5;
    const Machine m = load_machine("rw2");
    // 100 mm along X at F6000 (100 mm/s) from rest to rest at 3000 mm/s^2: 1/30 s up, 1/30 s
    // down over 10/6 mm each, the rest at 100 mm/s.
    Preflight one(m, 115200);
    one.scan("G28\nG1 X100 F6000\n");
    one.finish();
    const double want = 2 * (100.0 / 3000) + (100 - 2 * 100.0 * 100 / 6000) / 100;
    CHECK(one.seconds() == doctest::Approx(want).epsilon(1e-9));
    CHECK(one.drains().empty());
    // 2000 moves of 0.05 mm at 50 mm/s take about 1 ms each; each line is about 30 bytes, 31 ms
    // at 9600 baud: the planner runs dry from the start; at 10 Mbit/s it never does.
    std::string file = "G28\n";
    for (int i = 1; i <= 2000; ++i) file += "G1 X" + std::to_string(10 + 0.05 * i) + " Y10 F3000\n";
    Preflight slow(m, 9600), fast(m, 1e7);
    slow.scan(file), fast.scan(file);
    slow.finish(), fast.finish();
    MESSAGE("slow link: " << slow.summary() << "fast link: " << fast.summary());
    REQUIRE(!slow.drains().empty());
    CHECK(slow.drains().front().first <= 20);
    CHECK(slow.seconds_with_link() > 2000 * 0.03);
    CHECK(slow.seconds_with_link() > 10 * slow.seconds());
    CHECK(fast.drains().empty());
    CHECK(fast.seconds_with_link() == doctest::Approx(fast.seconds()).epsilon(0.05));
    CHECK(fast.seconds() == doctest::Approx(slow.seconds()));
}

TEST_CASE("preflight: a dwell lets the planner run out and waits its time; heating waits are counted apart") {
    using namespace xlate5;
    const Machine m = load_machine("rw2");
    // Each 100 mm move at F6000 (100 mm/s) from rest to rest at 3000 mm/s^2 (the planner runs out
    // before each dwell, as Marlin's G4 synchronizes): 1/30 s up and down over 10/6 mm each, the
    // rest at 100 mm/s. Dwells: P milliseconds, S seconds, S over P when both (Marlin's G4).
    const double stop_to_stop = 2 * (100.0 / 3000) + (100 - 2 * 100.0 * 100 / 6000) / 100;
    const std::string file = "G28\nG1 X100 F6000\nG4 P500\nG1 X200\nG04 S2\nG1 X300\nG4 P250 S1\nM109 S200\nM190 S60\nM104 S0\nG40\n";
    Preflight p(m, 115200);
    p.scan(file);
    p.finish();
    CHECK(p.waits().dwells == 3);
    CHECK(p.waits().dwell_seconds == doctest::Approx(0.5 + 2 + 1).epsilon(1e-12));
    CHECK(p.waits().heat_waits == 2);
    CHECK(p.seconds() == doctest::Approx(3 * stop_to_stop + 3.5).epsilon(1e-9));
    CHECK(p.json().find("\"dwells\": 3, \"dwell_seconds\": 3.5, \"heat_waits_not_included\": 2") != std::string::npos);
    CHECK(p.summary().find("3 dwells (G4) add 3.5 s") != std::string::npos);
    // Each block and each dwell is told at its line as it runs (the slicer's time lines are
    // rewritten from these): the dwells at lines 3, 5 and 7, in all the pre-flight's seconds.
    Preflight told(m, 115200);
    std::vector<std::pair<std::uint64_t, double>> runs;
    told.executed = [&](std::uint64_t line, double s) { runs.emplace_back(line, s); };
    told.scan(file);
    told.finish();
    double sum = 0;
    for (const auto& [line, s] : runs) sum += s;
    CHECK(sum == doctest::Approx(p.seconds()).epsilon(1e-12));
    const std::vector<std::pair<std::uint64_t, double>> dwells = {{3, 0.5}, {5, 2.0}, {7, 1.0}};
    std::vector<std::pair<std::uint64_t, double>> told_dwells;
    for (const auto& r : runs)
        if (r.first % 2 == 1) told_dwells.push_back(r);
    CHECK(told_dwells == dwells);
    // M400 stops the planner without a wait.
    Preflight m400(m, 115200);
    m400.scan("G28\nG1 X100 F6000\nM400\nG1 X200\n");
    m400.finish();
    CHECK(m400.seconds() == doctest::Approx(2 * stop_to_stop).epsilon(1e-9));
    // Klipper's G4 reads P (milliseconds) alone.
    Machine k = m;
    k.dialect.firmware = FirmwareDialect::Klipper;
    Preflight klipper(k, 115200);
    klipper.scan(file);
    klipper.finish();
    CHECK(klipper.waits().dwell_seconds == doctest::Approx(0.5 + 0 + 0.25).epsilon(1e-12));
    CHECK(klipper.seconds() == doctest::Approx(3 * stop_to_stop + 0.75).epsilon(1e-9));
}
