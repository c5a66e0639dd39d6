// SPDX-License-Identifier: GPL-3.0-or-later
// The keep-out stage (ADD_IN team, 2015): R normal to the path toward the nearest
// item, checked on the joints written (R is the firmware's A on addin4, the tip by FK) against
// the geometry computed here from the input: the source's figure-1 tube, long moves past several
// items sampled along their length, turns never pointing away, unwinding only on travel moves.
#include <doctest/doctest.h>

#include <cmath>
#include <sstream>

#include "helpers.hpp"
#include "translators/error.hpp"
#include "translators/pipeline/keep_out.hpp"
#include "translators/kinematics/kinematics.hpp"
#include "translators/machine/machine.hpp"
#include "translators/pipeline/translator.hpp"

using namespace xlate5;
using namespace xlate5::test;

namespace {

double wrap(double deg) { return deg - 360.0 * std::round(deg / 360.0); }

struct Step {
    std::string line;              // output line
    Eigen::Vector3d from, to;      // tip by FK
    double r0, r1;                 // R before and after
    bool prints;
};

// Every output move with the tip by FK and R (the firmware's A) at both ends.
std::vector<Step> steps_of(const Machine& m, const Kinematics& k, const std::string& out) {
    std::vector<double> q = m.home_joints();
    const int r = m.joint_index('R');
    REQUIRE(r >= 0);
    const char a = m.joints[std::size_t(r)].output;
    std::vector<Step> s;
    for (const auto& line : lines_of(out)) {
        if (line.empty() || line[0] == ';') continue;
        const auto w = words_of(line);
        if (!w.count('G')) continue;
        const double g = w.at('G');
        if (g == 28) q = m.home_joints();
        if (g != 0 && g != 1) continue;
        Step st{line, k.forward(q).tip, {}, q[std::size_t(r)], 0, w.count('E') && w.at('E') > 0};
        for (std::size_t j = 0; j < m.joints.size(); ++j)
            if (w.count(m.joints[j].output)) q[j] = w.at(m.joints[j].output);
        st.to = k.forward(q).tip;
        st.r1 = q[std::size_t(r)];
        (void)a;
        s.push_back(st);
    }
    return s;
}

std::string translate(const Kinematics& k, const KeepOutItems& items, const std::string& gcode) {
    TranslatorOptions o;
    o.input_name = "part.gcode";
    o.keep_out = &items;
    Translator t(k, o);
    t.set_lookback(Translator::kDefaultLookback);
    std::string out;
    std::istringstream in(gcode);
    std::string line;
    std::uint64_t n = 0;
    while (std::getline(in, line)) t.feed(line, ++n, out);
    t.finish(out);
    return out;
}

std::string tube(int layers, int steps, double cx, double cy, double radius) {
    std::ostringstream g;
    g << "G90\nM83\nG28\nG0 Z5 F3000\nG0 X" << cx + radius << " Y" << cy << "\n";
    char buf[160];
    for (int l = 0; l < layers; ++l) {
        g << "G0 Z" << 0.2 * (l + 1) << "\n";
        for (int i = 1; i <= steps; ++i) {
            const double a = 2 * kPi * i / steps;
            std::snprintf(buf, sizeof buf, "G1 X%.4f Y%.4f E%.5f F1800\n", cx + radius * std::cos(a), cy + radius * std::sin(a),
                          0.033 * 2 * radius * std::sin(kPi / steps));
            g << buf;
        }
    }
    return g.str();
}

// Direction (deg) of R, and of the item from p.
double toward(const Eigen::Vector2d& p, const Eigen::Vector2d& c) { return std::atan2(c.y() - p.y(), c.x() - p.x()) * 180 / kPi; }

}  // namespace

TEST_CASE("keep-out: the sliced tube with an item at its centre has R pointing at the centre on every printing move") {
    const Machine m = load_machine(std::string(XLATE5_MACHINE_DIR_FOR_TESTS) + "/addin4.toml");
    const Kinematics k(m);
    const KeepOutItems items = parse_keep_out("# x, y, height\n100, 100, 0\n", "items.csv");
    const int layers = 6, per_layer = 180;
    const auto steps = steps_of(m, k, translate(k, items, tube(layers, per_layer, 100, 100, 20)));
    const Eigen::Vector2d c(100, 100);
    const Joint& R = m.joints[std::size_t(m.joint_index('R'))];
    int printing = 0;
    double worst = 0;
    for (const Step& s : steps) {
        CHECK(s.r1 >= R.min);
        CHECK(s.r1 <= R.max);
        if (s.prints) {
            ++printing;
            CHECK(s.r0 == s.r1);  // R turns in place, never while printing
            const Eigen::Vector2d mid = 0.5 * (s.from + s.to).head<2>();
            const double err = std::abs(wrap(s.r1 - toward(mid, c)));
            worst = std::max(worst, err);
            // ... and normal to the move
            const Eigen::Vector2d d = (s.to - s.from).head<2>();
            CHECK(std::abs(std::abs(wrap(s.r1 - std::atan2(d.y(), d.x()) * 180 / kPi)) - 90) < m.motion.angle_tolerance);
        } else if ((s.to - s.from).head<2>().norm() < 1e-9 && s.to.z() == s.from.z() && s.r0 != s.r1) {
            // A turn in place: less than half a turn, pointing within 90 degrees of the item at both
            // ends, so it never points away from it.
            CHECK(std::abs(s.r1 - s.r0) < 180);
            CHECK(std::abs(wrap(s.r0 - toward(s.to.head<2>(), c))) < 90);
            CHECK(std::abs(wrap(s.r1 - toward(s.to.head<2>(), c))) < 90);
        } else if (std::abs(s.r1 - s.r0) > 180) {
            CHECK_MESSAGE(s.line.rfind("G0 ", 0) == 0, "R unwound on a line that is not a travel move: " << s.line);
        }
    }
    CHECK(printing == layers * per_layer);
    CHECK(worst < m.motion.angle_tolerance);
    MESSAGE("tube: worst R error " << worst << " deg over " << printing << " printing moves");
}

TEST_CASE("keep-out: long moves past several items are split where the nearest item changes; R never points away along them") {
    const Machine m = load_machine(std::string(XLATE5_MACHINE_DIR_FOR_TESTS) + "/addin4.toml");
    const Kinematics k(m);
    // Items at several heights; a zigzag of long printing moves over three layers.
    const KeepOutItems items = parse_keep_out("40,70,0\n100,30,0\n160,75,0.5\n95,120,0.3\n", "items.csv");
    std::ostringstream g;
    g << "G90\nM82\nG28\nG0 Z5 F3000\nG0 X10 Y52\nG0 Z0.2\n";
    double e = 0;
    const double ys[] = {52, 88, 55.5, 101, 48, 93.3};
    Eigen::Vector2d at(10, 52);
    for (int layer = 0; layer < 3; ++layer) {
        if (layer > 0) g << "G0 Z" << 0.2 + 0.3 * layer << "\n";
        for (int i = 0; i < 6; ++i) {
            const Eigen::Vector2d to(i % 2 ? 10 : 190, ys[(i + layer) % 6]);
            e += 0.03 * (to - at).norm();
            g << "G1 X" << to.x() << " Y" << to.y() << " E" << e << " F1500\n";
            at = to;
        }
    }
    const std::string out = translate(k, items, g.str());
    const auto steps = steps_of(m, k, out);
    int pieces = 0, sampled = 0;
    double e_out = 0;
    for (const auto& line : lines_of(out))
        if (const auto w = words_of(line.substr(0, line.find(';'))); w.count('E') && w.count('G') && w.at('G') == 1) e_out = w.at('E');
    CHECK(e_out == doctest::Approx(e));  // absolute E ends as written
    for (const Step& s : steps) {
        if (!s.prints) continue;
        ++pieces;
        CHECK(s.r0 == s.r1);
        // Sampled along the piece: R within 90 degrees of the nearest item (computed here). At a
        // piece's ends two items are equally near (that is where it was split), and the written
        // positions are rounded: points where the two nearest are within 0.01 mm are skipped.
        for (int i = 0; i <= 20; ++i) {
            const Eigen::Vector3d p = s.from + (s.to - s.from) * (i / 20.0);
            int best = -1;
            double bd = 0, second = 1e300;
            for (std::size_t j = 0; j < items.items.size(); ++j) {
                if (items.items[j].height > p.z() + 1e-6) continue;
                const double d = (items.items[j].centre - p.head<2>()).norm();
                if (best < 0 || d < bd) second = best < 0 ? second : bd, best = int(j), bd = d;
                else second = std::min(second, d);
            }
            REQUIRE(best >= 0);
            if (second - bd < 0.01) continue;
            ++sampled;
            CHECK_MESSAGE(std::abs(wrap(s.r1 - toward(p.head<2>(), items.items[std::size_t(best)].centre))) < 90 + 1e-6,
                          s.line << " at " << i << "/20");
        }
    }
    CHECK(pieces > 18);  // split: more printing pieces than the 18 input moves
    CHECK(sampled > 15 * pieces);
}

TEST_CASE("keep-out: an item on the line of a move is an error naming the input line; a machine without such a rotary is refused") {
    const Machine m = load_machine(std::string(XLATE5_MACHINE_DIR_FOR_TESTS) + "/addin4.toml");
    const Kinematics k(m);
    const KeepOutItems items = parse_keep_out("100, 100, 0\n", "items.csv");
    try {
        translate(k, items, "G90\nM83\nG28\nG0 X120 Y100 Z0.2\nG1 X130 Y100 E1 F1200\n");
        FAIL("no error");
    } catch (const InputError& e) {
        CHECK(e.line() == 5);
        CHECK(contains(e.message(), "items.csv line 1"));
        CHECK(contains(e.message(), "lies on the line"));
    }
    const Machine rw2 = load_machine(std::string(XLATE5_MACHINE_DIR_FOR_TESTS) + "/rw2.toml");
    const Kinematics krw(rw2);
    TranslatorOptions o;
    o.keep_out = &items;
    CHECK_THROWS_AS(Translator(krw, o), MachineError);
    // The items file: x, y, height, errors at line and column.
    try {
        parse_keep_out("1,2,3\n4,5\n", "i.csv");
        FAIL("no error");
    } catch (const InputError& e) {
        CHECK(e.line() == 2);
    }
    try {
        parse_keep_out("1,2,x3\n", "i.csv");
        FAIL("no error");
    } catch (const InputError& e) {
        CHECK(e.column() == 5);
    }
}

TEST_CASE("keep-out: a split move's relative E pieces add up to its E as written") {
    const Machine m = load_machine(std::string(XLATE5_MACHINE_DIR_FOR_TESTS) + "/addin4.toml");
    const Kinematics k(m);
    const KeepOutItems items = parse_keep_out("40,60,0\n100,45,0\n160,63,0\n", "items.csv");
    const std::string out = translate(k, items, "G90\nM83\nG28\nG0 X10 Y50 Z0.2 F3000\nG1 X190 Y52 E7.33333 F1200\n");
    double e = 0;
    int pieces = 0;
    for (const auto& line : lines_of(out))
        if (const auto w = words_of(line.substr(0, line.find(';'))); w.count('E') && w.count('G') && w.at('G') == 1) e += w.at('E'), ++pieces;
    CHECK(pieces == 3);  // split twice: item 1 -> 2 -> 3
    CHECK(std::abs(e - 7.33333) < 1e-9);
}
