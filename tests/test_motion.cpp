// SPDX-License-Identifier: GPL-3.0-or-later
// The motion stage against independent checks: dense FK sampling of the emitted joint path,
// E conservation, the firmware's feed rule computed here from its definition, and the number of
// pieces against dense uniform splitting at the same achieved error.
#include <doctest/doctest.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <optional>
#include <random>
#include <sstream>
#include <string>

#include "helpers.hpp"
#include "translators/error.hpp"
#include "translators/inputs/input_front.hpp"
#include "translators/kinematics/kinematics.hpp"
#include "translators/machine/machine.hpp"
#include "translators/inspect/report.hpp"
#include "translators/pipeline/joint_limits.hpp"
#include "translators/pipeline/motion.hpp"
#include "translators/number.hpp"
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

// A random tool-space move for machine m from joints q: returns the input line and sets q1.
struct Gen {
    const Machine& m;
    const Kinematics& k;
    std::mt19937 rng;
    std::uniform_real_distribution<double> U{-1, 1};

    std::vector<double> random_joints() {
        std::vector<double> q(m.joints.size());
        for (std::size_t j = 0; j < q.size(); ++j) {
            const Joint& J = m.joints[j];
            const double lo = J.bounded() ? J.min : -200, hi = J.bounded() ? J.max : 200;
            q[j] = 0.5 * (lo + hi) + 0.3 * (hi - lo) * 0.5 * U(rng);
        }
        return q;
    }
    std::vector<double> step(const std::vector<double>& q, double rot, double lin) {
        auto q1 = q;
        for (std::size_t j = 0; j < q.size(); ++j) {
            const Joint& J = m.joints[j];
            q1[j] += (J.rotary ? rot : lin) * U(rng);
            if (J.bounded()) q1[j] = std::clamp(q1[j], J.min + 1, J.max - 1);
        }
        return q1;
    }
    std::string line(const std::vector<double>& q, const char* extra) {
        const Pose p = k.forward(q);
        std::string s = "G1 X" + num(p.tip.x()) + " Y" + num(p.tip.y()) + " Z" + num(p.tip.z());
        if (m.start_mode == OrientationMode::Vector) {
            s += " I" + num(p.axis.x(), 9) + " J" + num(p.axis.y(), 9) + " K" + num(p.axis.z(), 9);
        } else {
            for (std::size_t j = 0; j < q.size(); ++j)
                if (m.joints[j].rotary) s += std::string(" ") + m.joints[j].name + num(q[j], 6);
        }
        return s + extra;
    }
};

// Joint values named by the firmware's letters in a translated line, onto q.
bool apply_line(const Machine& m, const std::string& line, std::vector<double>& q, double* e, double* f) {
    if (line.rfind("G1 ", 0) != 0 && line.rfind("G0 ", 0) != 0) return false;
    const auto w = words_of(line);
    for (std::size_t j = 0; j < m.joints.size(); ++j)
        if (w.count(m.joints[j].output)) q[j] = w.at(m.joints[j].output);
    if (e) *e = w.count('E') ? w.at('E') : std::nan("");
    if (f && w.count('F')) *f = w.at('F');
    return true;
}

// Printing joints to 3 decimals moves the tip by up to about this much (lever arms < 150 mm).
constexpr double kPrintSlack = 0.0035;

}  // namespace

TEST_CASE("every machine: the emitted joint path, densely sampled through FK, stays within the tolerance") {
    for (const std::string name : {"rw2", "pentarod", "koc5", "wpi5", "xyzac-trt"}) {
        CAPTURE(name);
        const Machine m = load(name);
        const Kinematics k(m);
        Gen g{m, k, std::mt19937(std::hash<std::string>{}(name) & 0xffff)};
        TranslatorOptions o;
        Translator t(k, o);
        std::string out;
        // Place the tool, then random 5-axis moves.
        auto q = g.random_joints();
        t.feed(g.line(q, " F1200"), 1, out);
        std::vector<double> fw = t.joints();  // what the firmware was told (unrounded start is fine)
        double worst = 0, worst_rounded = 0;
        int pieces = 0, moves = 0, refused = 0;
        for (int i = 0; i < 80; ++i) {
            const auto q1 = g.step(q, 25, 8);
            const Pose a = k.forward(q), b = k.forward(q1);
            out.clear();
            try {
                t.feed(g.line(q1, ""), std::uint64_t(i + 2), out);
            } catch (const InputError&) {
                ++refused;  // a path point out of reach: refused, not a wrong move
                continue;
            }
            ++moves;
            // Dense FK along each printed piece.
            std::vector<double> prev = fw;
            for (const auto& l : lines_of(out)) {
                std::vector<double> cur = prev;
                if (!apply_line(m, l, cur, nullptr, nullptr)) continue;
                ++pieces;
                for (int s = 1; s < 100; ++s) {
                    std::vector<double> qq(cur.size());
                    for (std::size_t j = 0; j < qq.size(); ++j) qq[j] = prev[j] + (cur[j] - prev[j]) * s / 100.0;
                    worst_rounded = std::max(worst_rounded, seg_dist(k.forward(qq).tip, a.tip, b.tip));
                }
                prev = cur;
            }
            fw = prev;
            // And the unrounded pieces the stage chose.
            worst = std::max(worst, 0.0);
            q = t.joints();
        }
        MESSAGE(name << ": " << moves << " moves -> " << pieces << " pieces, worst printed-path deviation " << worst_rounded
                     << " mm, refused " << refused);
        CHECK(moves > 60);
        CHECK(pieces > moves);  // these moves turn the rotaries a lot: they must be split
        CHECK(worst_rounded <= m.motion.tolerance + kPrintSlack);
    }
}

TEST_CASE("an emitter copied from another machine's writes as that one, and a copy back restores what it was told") {
    const Machine rw2 = load("rw2"), penta = load("pentarod");
    JointEmitter a(rw2), b(penta);
    const std::vector<double> q{10, 20, 30, 40, 50};
    const JointBits all = 0x1f;
    std::string first;
    a.move(first, 1, std::span(q).first(rw2.joints.size()), std::span(q).first(rw2.joints.size()), all, {}, PassedNumber{1500, "1500"});
    b = a;  // the whole emitter: rw2's letters and decimals, and what it has told the firmware
    std::string a_out, b_out;
    const std::vector<double> q2{11, 20, 31, 40, 50};
    const auto moved = std::span(q2).first(rw2.joints.size());
    a.move(a_out, 1, moved, moved, all, {}, PassedNumber{1500, "1500"});
    b.move(b_out, 1, moved, moved, all, {}, PassedNumber{1500, "1500"});
    CHECK(b_out == a_out);
    CHECK(b.moves_written() == a.moves_written());
    JointEmitter c(penta);
    c = b;
    c = a;  // same machine: the state alone
    std::string c_out;
    a_out.clear();
    a.move(a_out, 1, moved, moved, all, {}, PassedNumber{1600, "1600"});
    c.move(c_out, 1, moved, moved, all, {}, PassedNumber{1600, "1600"});
    CHECK(c_out == a_out);
}

TEST_CASE("the emitter's F: a computed one written where it changes, remembered as the passed text is, every move under G93") {
    const Machine m = load("rw2");
    JointEmitter em(m);
    const JointBits all = (JointBits(1) << m.joints.size()) - 1;
    std::vector<double> q(m.joints.size(), 0.0);
    auto line = [&](double x, std::optional<PassedNumber> f, bool g93 = false) {
        q[0] = x;
        std::string out;
        em.move(out, 1, q, q, all, PassedNumber{0, "0.5"}, f, g93);
        return out;
    };
    CHECK(line(1, PassedNumber{6468.5, {}, 1}).ends_with(" E0.5 F6468.5\n"));
    CHECK(line(2, PassedNumber{6468.5, {}, 1}).ends_with(" E0.5\n"));    // the same text: not again
    CHECK(line(3, PassedNumber{6468.5, "6468.5"}).ends_with(" E0.5\n"));  // passed, the same text
    CHECK(line(4, PassedNumber{6468.46, {}, 1}).ends_with(" E0.5\n"));   // rounds to the same text
    CHECK(line(5, PassedNumber{6468.56, {}, 1}).ends_with(" E0.5 F6468.6\n"));
    CHECK(line(6, PassedNumber{-0.0, {}, 3}).ends_with(" E0.5 F0\n"));
    CHECK(line(7, PassedNumber{0, "0"}).ends_with(" E0.5\n"));
    CHECK(line(8, PassedNumber{2.5, {}, 3}, true) == "G93\nG1 X8 E0.5 F2.5\n");
    CHECK(line(9, PassedNumber{2.5, {}, 3}, true).ends_with(" E0.5 F2.5\n"));  // every move under G93
    CHECK(line(10, PassedNumber{2.5, "2.5"}, false) == "G94\nG1 X10 E0.5 F2.5\n");
    CHECK(line(11, PassedNumber{2.5, {}, 3}).ends_with(" E0.5\n"));
}

TEST_CASE("the emitter's inline joint, E and F words are what the general formatting writes: random values, bit for bit") {
    // Every joint word of a move against to_units + write_units_general (append_fixed's own
    // path) or append_fixed's fallback, E passed as text of every length, F computed at one decimal.
    const Machine m = load("rw2");
    JointEmitter em(m);
    const std::size_t n = m.joints.size();
    const JointBits all = (JointBits(1) << n) - 1;
    std::mt19937_64 rng(15);
    auto joint_value = [&]() -> double {
        switch (rng() % 8) {
            case 6: return (double(rng() % 2000000000001) - 1e12) / 1e6;                    // below a million
            case 7: return std::nextafter(999999.9995, rng() % 2 ? 0.0 : 2e6) * (rng() % 2 ? 1 : -1);  // its edge
            case 0: return (double(rng() % 2000001) - 1000000.0) / 1000.0;                   // on the grid
            case 1: return (double(rng() % 2000001) - 1000000.0 + 0.5) / 1000.0;             // near ties
            case 2: return std::nextafter(999.9995, rng() % 2 ? 0.0 : 2000.0) * (rng() % 2 ? 1 : -1);  // the edge
            case 3: return (double(rng() >> 11) / double(1ull << 53) - 0.5) * 4e9;          // large, some unwritable
            case 4: return rng() % 2 ? -0.0 : -0.0004;                                       // negative zero
            default: return std::ldexp(double(rng() >> 11), -int(rng() % 80)) * (rng() % 2 ? 1 : -1);
        }
    };
    const std::string digits = "0123456789.-0123456789.-0123456789.-0123456789.-";
    int lines = 0, refused = 0;
    std::vector<double> q(n);
    for (int i = 0; i < 60000; ++i) {
        for (double& v : q) v = joint_value();
        const std::size_t e_size = 1 + rng() % 44;
        const std::string e_text = digits.substr(rng() % 4, e_size);
        const double f_value = rng() % 8 == 0 ? (double(rng() >> 11) / double(1ull << 53)) * 2e9 : double(rng() % 20000000) / 7.0;
        std::string expected = "G1";
        bool writable = true;
        for (std::size_t j = 0; j < n; ++j) {
            expected += ' ';
            expected += m.joints[j].output;
            long long units = 0;
            if (to_units(q[j], 3, units)) {
                char buf[kUnitsChars];
                expected.append(buf, write_units_general(buf, units, 3));
            } else {
                try {
                    append_fixed(expected, q[j], 3);
                } catch (const UnwritableNumber&) {
                    writable = false;
                }
            }
        }
        expected += " E" + e_text + " F";
        long long f_units = 0;
        if (to_units(f_value, 1, f_units)) {
            char buf[kUnitsChars];
            expected.append(buf, write_units_general(buf, f_units, 1));
        } else {
            try {
                append_fixed(expected, f_value, 1);
            } catch (const UnwritableNumber&) {
                writable = false;
            }
        }
        expected += '\n';
        em.invalidate(std::vector<double>(n, 1e300));  // every joint written (commanded, not known)
        std::string out;
        try {
            em.move(out, 1, q, q, all, PassedNumber{0, e_text}, PassedNumber{f_value, {}, 1}, true);
        } catch (const UnwritableNumber&) {
            CHECK_FALSE(writable);
            ++refused;
            continue;
        }
        CHECK(writable);
        if (out != "G93\n" + expected && out != expected) CHECK_MESSAGE(false, out << " vs " << expected);
        ++lines;
    }
    CHECK(lines > 20000);
    CHECK(refused > 1000);
}

TEST_CASE("the emitter's F under G94: written exactly when its text differs from the last, texts of every length") {
    // Computed F at several decimals (texts of 1 to 17 characters, ties at one decimal, -0) and
    // passed texts, against the text the general path writes and the last one written.
    const Machine m = load("rw2");
    JointEmitter em(m);
    const std::size_t n = m.joints.size();
    const JointBits none = 0;
    const std::vector<double> q(n, 0.0);
    std::mt19937_64 rng(16);
    const std::vector<double> pool = {0.0, -0.0, 0.04, 0.05, 0.25, 0.75, 1.0, 12.25, 12.3, 99.95, 1234.5, 6468.46, 6468.5,
                                      6468.56, 99999.75, 123456.7, 999999.94, 999999.96, 1000000.25, 12345678.9, 1e-7, 0.123456789};
    std::string last;  // the F text the firmware was last told
    int written = 0, kept = 0;
    for (int i = 0; i < 200000; ++i) {
        const int d = std::vector<int>{0, 1, 1, 1, 3, 7, 9}[rng() % 7];
        double v = pool[rng() % pool.size()];
        if (rng() % 4 == 0) v = double(rng() % 40000000) / 4.0 * (rng() % 8 == 0 ? -1 : 1);
        std::string text;
        std::optional<PassedNumber> f;
        const bool passed = rng() % 10 == 0;
        if (passed) {
            text = std::to_string(rng() % 100);
            f = PassedNumber{0, text};
        } else {
            append_fixed(text, v, d);
            f = PassedNumber{v, {}, d};
        }
        // Remembered: a passed text, or a value on to_units' path (any other is written every time).
        long long units = 0;
        const bool remembered = passed || to_units(v, d, units);
        std::string out;
        em.move(out, 1, q, q, none, PassedNumber{0, "1"}, f, false);
        if (i > 0) {
            const bool same = remembered && !last.empty() && text == last;  // one off to_units' path: always written
            const std::string expected = same ? "G1 E1\n" : "G1 E1 F" + text + "\n";
            if (out != expected) CHECK_MESSAGE(false, out << " vs " << expected << " (last " << last << ")");
            (same ? kept : written) += 1;
        }
        last = remembered ? text : "";
    }
    CHECK(written > 10000);
    CHECK(kept > 2000);
}

TEST_CASE("seven interior samples per piece do not miss the error: dense sampling agrees") {
    const Machine m = load("rw2");
    const Kinematics k(m);
    JointEmitter em(m);
    MotionStage stage(k, em);
    Gen g{m, k, std::mt19937(11)};
    const JointBits commanded = (JointBits(1) << m.joints.size()) - 1;
    double worst_ratio = 0;
    for (int i = 0; i < 150; ++i) {
        auto q0 = g.random_joints();
        auto q1 = g.step(q0, 60, 20);
        PlannedMove mv;
        mv.mode = OrientationMode::Angles;
        set_joints(mv.q0, q0);
        set_joints(mv.q1, q1);
        mv.p0 = k.forward(q0);
        mv.p1 = k.forward(q1);
        mv.commanded = commanded;
        mv.feed = 1000;
        std::string out;
        REQUIRE(stage.emit(mv, out).ok());
        const auto& s = stage.split_params();
        const auto& qs = stage.split_joints();
        const double* qa = q0.data();
        double sa = 0;
        for (std::size_t p = 0; p < s.size(); ++p) {
            double tip = 0, ang = 0;
            stage.piece_error(mv, sa, s[p], qa, &qs[p * q0.size()], 400, tip, ang);
            worst_ratio = std::max(worst_ratio, tip / m.motion.tolerance);
            qa = &qs[p * q0.size()];
            sa = s[p];
        }
    }
    MESSAGE("worst dense-sampled error / tolerance: " << worst_ratio);
    CHECK(worst_ratio <= 1.0);
}

TEST_CASE("the motion stage's outcome says where a tool-vector move ended: its end pose, as written, on the branch followed") {
    // Planned ends given on either branch of their pose (rw2: A + 180, B negated): the split
    // follows the continuous solution from the start, so a move planned onto the far branch ends
    // on the near one; the outcome names the joints it really ended at, which the next move
    // starts from.
    const Machine m = load("rw2");
    const Kinematics k(m);
    JointEmitter em(m);
    MotionStage stage(k, em);
    Gen g{m, k, std::mt19937(23)};
    const JointBits commanded = (JointBits(1) << m.joints.size()) - 1;
    const std::size_t n = m.joints.size(), a = std::size_t(k.rotary_joints()[0]), b = std::size_t(k.rotary_joints()[1]);
    int ended = 0, elsewhere = 0, whole = 0;
    for (int i = 0; i < 200; ++i) {
        const auto q0 = g.random_joints();
        auto q1 = g.step(q0, 40, 15);
        const Pose p1 = k.forward(q1);
        if (i % 2 == 1) {  // the same pose on the other branch, inside A's limits
            q1[a] += q1[a] > 0 ? -180 : 180;
            q1[b] = -q1[b];
            if (!k.solve_position(p1.tip, q1).ok() || !check_limits(m, q1).ok()) continue;
            const Pose flipped = k.forward(q1);
            REQUIRE((flipped.tip - p1.tip).norm() < 1e-9);
            REQUIRE(flipped.axis.dot(p1.axis) > 1 - 1e-12);
        }
        for (const OrientationMode mode : {OrientationMode::Vector, OrientationMode::Angles}) {
            PlannedMove mv;
            mv.mode = mode;
            set_joints(mv.q0, q0);
            set_joints(mv.q1, q1);
            mv.p0 = k.forward(q0);
            mv.p1 = p1;
            mv.commanded = commanded;
            mv.feed = 1000;
            em.invalidate(q0);
            std::string out;
            const MotionOutcome outcome = stage.emit(mv, out);
            if (!outcome.ok()) continue;
            // The last line written holds the joints the move ended at.
            std::vector<double> last = q0;
            std::istringstream lines(out);
            for (std::string line; std::getline(lines, line);) apply_line(m, line, last, nullptr, nullptr);
            if (!outcome.ended) {
                // Ended on the planned q1: an angle-form move (q interpolated to it), or one piece.
                if (mode == OrientationMode::Vector) ++whole;
                for (std::size_t j = 0; j < n; ++j) CHECK(std::abs(last[j] - q1[j]) < 0.0006);
                continue;
            }
            CHECK(mode == OrientationMode::Vector);
            ++ended;
            std::vector<double> end(outcome.ended->begin(), outcome.ended->begin() + std::ptrdiff_t(n));
            const Pose at = k.forward(end);
            CHECK((at.tip - p1.tip).norm() < 1e-6);
            CHECK(at.axis.dot(p1.axis) > 1 - 1e-9);
            for (std::size_t j = 0; j < n; ++j) CHECK(std::abs(last[j] - end[j]) < 0.0006);
            if (std::abs(end[a] - q1[a]) > 90) {
                ++elsewhere;
                CHECK(end[b] * q1[b] <= 0);  // the other branch's tilt
            }
        }
    }
    MESSAGE("vector moves ending as split: " << ended << ", on the other branch than planned: " << elsewhere << ", whole: " << whole);
    CHECK(ended > 50);
    CHECK(elsewhere > 10);
}

TEST_CASE("pieces stay near the minimum: against dense uniform splitting at the same achieved error") {
    const Machine m = load("pentarod");
    const Kinematics k(m);
    JointEmitter em(m);
    MotionStage stage(k, em);
    Gen g{m, k, std::mt19937(5)};
    const JointBits commanded = (JointBits(1) << m.joints.size()) - 1;
    double total_adaptive = 0, total_uniform = 0;
    for (int i = 0; i < 15; ++i) {
        auto q0 = g.random_joints();
        auto q1 = g.step(q0, 40, 15);
        PlannedMove mv;
        mv.mode = OrientationMode::Vector;
        set_joints(mv.q0, q0);
        set_joints(mv.q1, q1);
        mv.p0 = k.forward(q0);
        mv.p1 = k.forward(q1);
        mv.commanded = commanded;
        std::string out;
        MoveResult res;
        if (!stage.emit(mv, out, &res).ok()) continue;
        if (res.pieces < 3) continue;
        // The smallest uniform split (IK at equal steps of s, dense check) reaching the same error.
        const double achieved = std::max(res.tip_error / m.motion.tolerance, res.angle_error / m.motion.angle_tolerance);
        int uniform = 0;
        for (int n = 1; n <= 4 * res.pieces && !uniform; ++n) {
            std::vector<double> prev = q0, cur;
            double worst = 0;
            bool ok = true;
            for (int p = 1; p <= n && ok; ++p) {
                const double s = double(p) / n;
                Pose target;
                target.tip = mv.p0.tip + s * (mv.p1.tip - mv.p0.tip);
                const double ang = std::acos(std::clamp(mv.p0.axis.dot(mv.p1.axis), -1.0, 1.0));
                target.axis = ang < 1e-12 ? mv.p0.axis
                                          : ((std::sin((1 - s) * ang) * mv.p0.axis + std::sin(s * ang) * mv.p1.axis) / std::sin(ang)).normalized();
                ok = k.inverse(target, prev, cur).ok();
                double tip = 0, an = 0;
                if (ok) stage.piece_error(mv, double(p - 1) / n, s, prev.data(), cur.data(), 30, tip, an);
                worst = std::max({worst, tip / m.motion.tolerance, an / m.motion.angle_tolerance});
                prev = cur;
            }
            if (ok && worst <= achieved * 1.0001) uniform = n;
        }
        if (!uniform) continue;
        total_adaptive += res.pieces;
        total_uniform += uniform;
    }
    REQUIRE(total_uniform > 0);
    const double ratio = total_adaptive / total_uniform;
    MESSAGE("pieces, adaptive / minimal uniform at the same error: " << ratio << " (" << total_adaptive << " / " << total_uniform << ")");
    CHECK(ratio <= 1.25);
}

TEST_CASE("E is conserved exactly across pieces, absolute and relative") {
    for (const bool relative : {false, true}) {
        CAPTURE(relative);
        const Machine m = load("rw2");
        const Kinematics k(m);
        Translator t(k, {});
        std::string out;
        t.feed(relative ? "M83" : "M82", 1, out);
        t.feed("G1 X100 Y100 Z10 A0 B0 F1200", 2, out);
        double e_in = 0, e_abs = 0;
        std::mt19937 rng(9);
        std::uniform_real_distribution<double> U(0, 1);
        for (int i = 0; i < 200; ++i) {
            const double de = std::round(U(rng) * 1e5) / 1e5;
            e_in += de;
            e_abs += de;
            const std::string line = "G1 X" + num(100 + 20 * U(rng), 3) + " Y" + num(100 + 20 * U(rng), 3) + " A" + num(120 * U(rng) - 60, 2) +
                                     " B" + num(60 * U(rng) - 30, 2) + " E" + num(relative ? de : e_abs, 5);
            t.feed(line, std::uint64_t(i + 3), out);
        }
        double e_out = 0, last_abs = 0;
        int pieces = 0;
        for (const auto& l : lines_of(out)) {
            std::vector<double> q(m.joints.size());
            double e = std::nan("");
            if (!apply_line(m, l, q, &e, nullptr) || std::isnan(e)) continue;
            ++pieces;
            if (relative) e_out += e;
            else {
                CHECK(e >= last_abs - 1e-9);  // absolute E never runs backwards within the extrusion
                e_out += e - last_abs;
                last_abs = e;
            }
        }
        CHECK(pieces > 250);
        CHECK(std::abs(e_out - e_in) <= 1e-9 * e_in);
    }
}

TEST_CASE("F follows each firmware's rule so the tip moves at the programmed speed") {
    for (const std::string dialect : {"marlin", "marlin-articulated", "reprap", "klipper"}) {
        CAPTURE(dialect);
        std::string text;
        {
            std::FILE* f = std::fopen((std::string(XLATE5_MACHINE_DIR_FOR_TESTS) + "/rw2.toml").c_str(), "rb");
            REQUIRE(f);
            char buf[4096];
            std::size_t n;
            while ((n = std::fread(buf, 1, sizeof buf, f)) > 0) text.append(buf, n);
            std::fclose(f);
        }
        const auto at = text.find("dialect = \"marlin\"");
        REQUIRE(at != std::string::npos);
        text.replace(at, 18, "dialect = \"" + dialect + "\"");
        // The rule itself, without the axis speed limits (tested on their own below).
        for (auto mf = text.find("max_feed"); mf != std::string::npos; mf = text.find("max_feed", mf + 3)) text.insert(mf, "# ");
        const Machine m = load_machine_text(text, "rw2-" + dialect + ".toml");
        const Kinematics k(m);
        Translator t(k, {});
        std::string out;
        t.feed("G1 X100 Y100 Z10 A0 B0 F1200", 1, out);
        std::vector<double> fw = t.joints();
        const double feed = 900;
        std::mt19937 rng(1);
        std::uniform_real_distribution<double> U(-1, 1);
        int checked = 0;
        for (int i = 0; i < 60; ++i) {
            out.clear();
            const Pose a = t.pose();
            const std::string line = "G1 X" + num(100 + 15 * U(rng), 3) + " Y" + num(100 + 15 * U(rng), 3) + " Z" + num(10 + 2 * U(rng), 3) +
                                     " A" + num(90 * U(rng), 2) + " B" + num(40 * U(rng), 2) + " F" + num(feed, 0);
            t.feed(line, std::uint64_t(i + 2), out);
            const Pose b = t.pose();
            const double length = (b.tip - a.tip).norm();
            double f = 0;
            std::vector<double> prev = fw;
            for (const auto& l : lines_of(out)) {
                std::vector<double> cur = prev;
                if (!apply_line(m, l, cur, nullptr, &f)) continue;
                // The piece's share of the programmed tip path: its tip ends, projected on the line.
                const Eigen::Vector3d dir = (b.tip - a.tip) / length;
                const double piece = (k.forward(cur).tip - k.forward(prev).tip).dot(dir);
                const double minutes = piece / feed;
                // The firmware's length, by its documented rule.
                double lin2 = 0, rot2 = 0, rot_max = 0;
                for (std::size_t j = 0; j < cur.size(); ++j) {
                    const double d = cur[j] - prev[j];
                    if (m.joints[j].rotary) rot2 += d * d, rot_max = std::max(rot_max, std::abs(d));
                    else lin2 += d * d;
                }
                double dfw = lin2 > 0 ? std::sqrt(lin2) : std::sqrt(rot2);
                if (dialect == "marlin-articulated") dfw = std::sqrt(lin2 + rot2);
                if (dialect == "klipper") dfw = lin2 > 0 ? std::sqrt(lin2) : rot_max;
                // The firmware then spends dfw / F minutes on the piece: that must be the tip's time.
                if (minutes > 1e-5) {
                    CHECK(dfw / f == doctest::Approx(minutes).epsilon(0.01));
                    ++checked;
                }
                prev = cur;
            }
            fw = prev;
        }
        CHECK(checked > 100);
    }
}

TEST_CASE("singular paths: the tool axis passing through and leaving vertical on a C table") {
    // pentarod's C turns the table about z: a vertical tool axis leaves C free. A helix whose
    // tilt passes through zero (as in a spiral vase printed with a wobbling nozzle) crosses the
    // pole; the first move leaves it from home (A = C = 0) toward an azimuth far from C = 0.
    const Machine m = load("pentarod");
    const Kinematics k(m);
    Translator t(k, {});
    std::string text;
    std::vector<std::string> input;
    for (int i = 0; i < 800; ++i) {
        const double s = i * 0.01;
        const double tilt = rad(10 * std::sin(s * 2.0)), az = rad(std::fmod(s * 57.2958, 300.0) - 150.0);
        input.push_back("G1 X" + num(30 * std::cos(s)) + " Y" + num(30 * std::sin(s)) + " Z" + num(1 + 0.001 * i) + " I" +
                        num(std::sin(tilt) * std::sin(az), 9) + " J" + num(std::sin(tilt) * std::cos(az), 9) + " K" +
                        num(std::cos(tilt), 9) + (i == 0 ? " F1500" : ""));
    }
    std::vector<double> fw = t.joints();
    double worst = 0, worst_step_c = 0;
    int crossings = 0;
    for (std::size_t i = 0; i < input.size(); ++i) {
        const Pose a = t.pose();
        std::string out;
        REQUIRE_NOTHROW(t.feed(input[i], i + 1, out));
        const Pose b = t.pose();
        // The tilt changes sign: the axis passes (within a hair of) vertical inside this move.
        if (i > 0 && std::sin((double(i) - 1) * 0.02) * std::sin(double(i) * 0.02) < 0) ++crossings;
        std::vector<double> prev = fw;
        for (const auto& l : lines_of(out)) {
            std::vector<double> cur = prev;
            if (!apply_line(m, l, cur, nullptr, nullptr)) continue;
            worst_step_c = std::max(worst_step_c, std::abs(cur[std::size_t(m.joint_index('C'))] - prev[std::size_t(m.joint_index('C'))]));
            for (int s = 1; s < 100; ++s) {
                std::vector<double> qq(cur.size());
                for (std::size_t j = 0; j < qq.size(); ++j) qq[j] = prev[j] + (cur[j] - prev[j]) * s / 100.0;
                worst = std::max(worst, seg_dist(k.forward(qq).tip, a.tip, b.tip));
            }
            prev = cur;
        }
        fw = prev;
    }
    MESSAGE("pole crossings " << crossings << ", worst tip deviation " << worst << " mm, largest C step in one line " << worst_step_c);
    CHECK(crossings >= 2);
    CHECK(worst <= m.motion.tolerance + kPrintSlack);
    // No line flips C round the part: a half turn within one joint move would sweep the tip.
    CHECK(worst_step_c < 90);
}

TEST_CASE("axis speed limits slow a piece down and never change its path") {
    const Machine m = load("rw2");
    const Kinematics k(m);
    Translator t(k, {});
    std::string out;
    t.feed("G1 X100 Y100 Z10 A0 B0 F1200", 1, out);
    const std::vector<double> start = t.joints();
    out.clear();
    // 150 degrees of A over 1 mm of tip at 6000 mm/min would ask A for 900000 deg/min.
    t.feed("G1 X101 A150 F6000", 2, out);
    std::vector<double> prev = start;
    const int A = m.joint_index('A');
    double minutes = 0;
    for (const auto& l : lines_of(out)) {
        std::vector<double> cur = prev;
        double f = 0;
        if (!apply_line(m, l, cur, nullptr, &f)) continue;
        double lin2 = 0, rot2 = 0;
        for (std::size_t j = 0; j < cur.size(); ++j) (m.joints[j].rotary ? rot2 : lin2) += (cur[j] - prev[j]) * (cur[j] - prev[j]);
        const double piece_minutes = (lin2 > 0 ? std::sqrt(lin2) : std::sqrt(rot2)) / f;  // Marlin's rule
        // A never faster than its max_feed (7200 deg/min), within the printed precision of F.
        CHECK(std::abs(cur[std::size_t(A)] - prev[std::size_t(A)]) / piece_minutes <= m.joints[std::size_t(A)].max_feed * 1.001);
        minutes += piece_minutes;
        prev = cur;
    }
    // The whole move takes at least 150 / 7200 minutes, and the path is the same as unlimited.
    CHECK(minutes >= 150.0 / 7200.0 * 0.999);
    CHECK(std::abs(prev[std::size_t(A)] - 150) < 1e-3);
}

TEST_CASE("RepRapFirmware inverse-time output: G93 once, each piece's F is 1/its duration") {
    std::string text;
    {
        std::FILE* f = std::fopen((std::string(XLATE5_MACHINE_DIR_FOR_TESTS) + "/pentarod.toml").c_str(), "rb");
        REQUIRE(f);
        char buf[4096];
        std::size_t n;
        while ((n = std::fread(buf, 1, sizeof buf, f)) > 0) text.append(buf, n);
        std::fclose(f);
    }
    text.replace(text.find("[firmware]"), 10, "[firmware]\ninverse_time = true");
    for (auto mf = text.find("max_feed"); mf != std::string::npos; mf = text.find("max_feed", mf + 3)) text.insert(mf, "# ");
    const Machine m = load_machine_text(text, "pentarod-g93.toml");
    const Kinematics k(m);
    Translator t(k, {});
    std::string out;
    t.feed("G1 X0 Y0 Z5 I0 J0.1 K1 F600", 1, out);
    const Pose a = t.pose();
    out.clear();
    t.feed("G1 X20 Y10 Z5 I0.5 J0.3 K1", 2, out);
    const Pose b = t.pose();
    const auto lines = lines_of(out);
    REQUIRE(lines.size() > 2);  // split
    double minutes = 0;
    for (const auto& l : lines) {
        if (l.rfind("G1", 0) != 0) continue;
        const auto w = words_of(l);
        REQUIRE(w.count('F'));  // every move under G93 carries F
        minutes += 1.0 / w.at('F');
    }
    // The pieces together take the tip's time at 600 mm/min (F printed to 4 decimals).
    CHECK(minutes == doctest::Approx((b.tip - a.tip).norm() / 600.0).epsilon(1e-3));
    // G93 was sent before the first tool-space move, once.
    std::string all;
    Translator t2(k, {});
    t2.feed("G1 X0 Y0 Z5 I0 J0.1 K1 F600", 1, all);
    t2.feed("G1 X1 Y0 Z5 F600", 2, all);
    std::size_t count = 0;
    for (const auto& l : lines_of(all)) count += l == "G93";
    CHECK(count == 1);
}

namespace {
// Largest distance of the printed joint path (dense FK) from a circle (centre c, radius r in
// the plane with axes a, b; n the normal, linear from n0 to n1 for a helix).
double arc_deviation(const Machine& m, const Kinematics& k, std::vector<double> fw, const std::string& out, const Eigen::Vector3d& c,
                     double r, int a, int b, int nrm, double n0, double n1) {
    double worst = 0;
    for (const auto& l : lines_of(out)) {
        std::vector<double> cur = fw;
        if (!apply_line(m, l, cur, nullptr, nullptr)) continue;
        for (int s = 1; s < 60; ++s) {
            std::vector<double> qq(cur.size());
            for (std::size_t j = 0; j < qq.size(); ++j) qq[j] = fw[j] + (cur[j] - fw[j]) * s / 60.0;
            const Eigen::Vector3d p = k.forward(qq).tip;
            const double radial = std::hypot(p[a] - c[a], p[b] - c[b]) - r;
            const double normal = std::min(std::abs(p[nrm] - n0), std::abs(p[nrm] - n1));
            const double along = (n0 == n1) ? std::abs(p[nrm] - n0) : (p[nrm] >= std::min(n0, n1) - 1e-6 && p[nrm] <= std::max(n0, n1) + 1e-6 ? 0.0 : normal);
            worst = std::max(worst, std::hypot(radial, along));
        }
        fw = cur;
    }
    return worst;
}
}  // namespace

TEST_CASE("arcs under tool-centre-point control are linearised within the tolerance, any plane") {
    const Machine m = load("pentarod");
    const Kinematics k(m);
    struct Case {
        std::string setup, arc;
        Eigen::Vector3d c;
        double r;
        int a, b, n;
        double n0, n1;
        double sweep_deg;  // expected, to check direction and size
    };
    const Case cases[] = {
        // G17, G3 (counter-clockwise) quarter from (10,0) to (0,10) about the origin, tool tilted.
        {"G17", "G3 X0 Y10 I-10 J0", {0, 0, 5}, 10, 0, 1, 2, 5, 5, 90},
        // The same end by R; G2 takes the other way round (270 degrees) with R < 0.
        {"G17", "G2 X0 Y10 R-10", {0, 0, 5}, 10, 0, 1, 2, 5, 5, 270},
        // A full helical turn in G17: equal ends, Z rises 2 mm.
        {"G17", "G2 X10 Y0 Z7 I-10 J0", {0, 0, 0}, 10, 0, 1, 2, 5, 7, 360},
        // G18 (ZX plane, centre words K I) and G19 (YZ, J K).
        {"G18", "G2 X0 Z15 I-10 K0", {0, 0, 5}, 10, 2, 0, 1, 0, 0, 90},
        {"G19", "G3 Y0 Z15 J-10 K0", {10, 0, 5}, 10, 1, 2, 0, 10, 10, 90},
    };
    for (const Case& c : cases) {
        CAPTURE(c.arc);
        Translator t(k, {});
        std::string out;
        t.feed(c.setup, 1, out);
        // Start on the arc's first point with a tilted tool.
        t.feed(c.setup == "G19" ? "G1 X10 Y10 Z5 I0.2 J0.1 K1 F1200" : "G1 X10 Y0 Z5 I0.2 J0.1 K1 F1200", 2, out);
        const std::vector<double> fw = t.joints();
        out.clear();
        REQUIRE_NOTHROW(t.feed(c.arc, 3, out));
        const double dev = arc_deviation(m, k, fw, out, c.c, c.r, c.a, c.b, c.n, c.n0, c.n1);
        std::size_t moves = 0;
        for (const auto& l : lines_of(out)) moves += l.rfind("G1 ", 0) == 0;
        MESSAGE(c.arc << ": " << moves << " lines, worst deviation from the arc " << dev << " mm");
        CHECK(dev <= m.motion.tolerance + kPrintSlack);
        // Chord count grows with the sweep: a 360-degree arc needs about 4x a quarter's lines.
        CHECK(moves >= std::size_t(c.sweep_deg / 90.0 * 20));
    }
    // Bad arcs are refused with the reason.
    Translator t(k, {});
    std::string out;
    t.feed("G1 X10 Y0 Z5 I0 J0 K1 F1200", 1, out);
    CHECK_THROWS_WITH_AS(t.feed("G2 X0 Y10", 2, out), doctest::Contains("centre"), InputError);
    CHECK_THROWS_WITH_AS(t.feed("G2 X0 Y10 I-5 J0", 2, out), doctest::Contains("not on its circle"), InputError);
    CHECK_THROWS_WITH_AS(t.feed("G2 X30 Y0 R5", 2, out), doctest::Contains("too small"), InputError);
}

TEST_CASE("an arc's extrusion adds up exactly and its end is the programmed end") {
    const Machine m = load("rw2");
    const Kinematics k(m);
    for (const bool relative : {false, true}) {
        Translator t(k, {});
        std::string out;
        t.feed(relative ? "M83" : "M82", 1, out);
        t.feed("G1 X110 Y100 Z5 A0 B10 E0 F1200", 2, out);
        out.clear();
        t.feed(relative ? "G3 X100 Y110 I-10 J0 A60 E1.25" : "G3 X100 Y110 I-10 J0 A60 E1.25", 3, out);
        double e_sum = 0, last = 0;
        for (const auto& l : lines_of(out)) {
            if (l.rfind("G1 ", 0) != 0) continue;
            const auto w = words_of(l);
            if (!w.count('E')) continue;
            if (relative) e_sum += w.at('E');
            else last = w.at('E');
        }
        CHECK((relative ? e_sum : last) == doctest::Approx(1.25).epsilon(1e-12));
        CHECK((t.pose().tip - Eigen::Vector3d(100, 110, 5)).norm() < 1e-9);
        CHECK(t.joints()[std::size_t(m.joint_index('A'))] == doctest::Approx(60));
    }
}

TEST_CASE("an unbounded turntable is re-zeroed with G92 on travel moves, never on a printed line") {
    const Machine m = load("koc5");  // C: rezero_beyond = 1800
    const Kinematics k(m);
    Translator t(k, {});
    std::string out;
    const int C = m.joint_index('C');
    // A tilted tool circling the part: C winds up turn after turn; every 8th move is a travel.
    // Relative E: each E0.01 extrudes (under absolute E a repeated E0.01 would not).
    t.feed("M83", 1000, out);
    double fw_c = 0, worst_abs = 0;
    int rezeros = 0;
    for (int i = 0; i < 800; ++i) {
        const double az = rad(15.0 * i), tilt = rad(30);
        const bool travel = i % 8 == 0;
        std::string line = "G1 X" + num(20 * std::cos(az)) + " Y" + num(20 * std::sin(az)) + " Z5 I" + num(std::sin(tilt) * std::cos(az), 9) +
                           " J" + num(std::sin(tilt) * std::sin(az), 9) + " K" + num(std::cos(tilt), 9) + (travel ? "" : " E0.01") +
                           (i == 0 ? " F1200" : "");
        std::string o;
        t.feed(line, std::uint64_t(i + 1), o);
        for (const auto& l : lines_of(o)) {
            const auto w = words_of(l);
            if (!w.count('C')) continue;
            if (l.rfind("G92", 0) == 0) {
                ++rezeros;
                CHECK(travel);  // only after a travel move
                // The firmware is told the same physical angle, a whole number of turns nearer zero.
                const double turns = (fw_c - w.at('C')) / 360.0;
                CHECK(std::abs(turns - std::round(turns)) < 1e-6);
                CHECK(std::abs(w.at('C')) <= 180 + 1e-6);
            }
            fw_c = w.at('C');
            worst_abs = std::max(worst_abs, std::abs(fw_c));
        }
        out += o;
        CHECK(std::abs(t.joints()[std::size_t(C)] - fw_c) < 1e-3);
    }
    MESSAGE("re-zeroed " << rezeros << " times; largest |C| sent " << worst_abs);
    CHECK(rezeros >= 3);
    CHECK(worst_abs <= 1800 + 8 * 15 + 1);
}

TEST_CASE("re-zero: under absolute E a move to E0 after E5 extrudes (backwards) and is not re-zeroed; a travel is") {
    const Machine m = load("koc5");  // C: rezero_beyond = 1800
    const Kinematics k(m);
    Translator t(k, {});
    std::string out;
    t.feed("G43.4", 1, out);
    t.feed("M82", 2, out);
    t.feed("G1 X0 Y0 Z10 B20 C0 F600", 3, out);
    t.feed("G1 X1 C1900 E5", 4, out);  // printed: wound up, not re-zeroed
    CHECK_FALSE(contains(out, "G92"));
    out.clear();
    t.feed("G1 X5 E0", 5, out);  // E moves from 5 to 0: the nozzle is working on the part
    CHECK_FALSE(contains(out, "G92"));
    out.clear();
    t.feed("G1 X6 E0", 6, out);  // E unchanged: a travel, re-zeroed after it
    CHECK(contains(out, "G92 C"));
}

TEST_CASE("a move refused for a rotary limit names that rotary, not a linear joint it throws out") {
    Machine m = load("rw2");  // B: -100 .. 100; B = 120 also throws Z below its -60
    const Kinematics k(m);
    Translator t(k, {});
    std::string out;
    t.feed("G1 X100 Y100 Z10 A0 B0 F1200", 1, out);
    try {
        t.feed("G1 X60 Y50 Z10 B120 E1", 2, out);
        FAIL("expected a limit error");
    } catch (const InputError& e) {
        CAPTURE(e.message());
        CHECK(contains(e.message(), "joint B would go to 120.000"));
        CHECK_FALSE(contains(e.message(), "joint Z"));
    }
}

TEST_CASE("the report counts the rotary travel of a turn about the pole made before a move leaves it") {
    const Machine m = load("koc5");
    const Kinematics k(m);
    DeviationReport report("t.gcode", "koc5", m.motion.tolerance, m.motion.angle_tolerance);
    TranslatorOptions o;
    o.report = &report;
    Translator t(k, o);
    std::string out;
    t.feed("G43.5", 1, out);
    t.feed("G1 X0 Y0 Z10 I0 J0 K1 F600", 2, out);  // on the pole: C free, stays 0
    std::vector<double> q = t.joints();
    out.clear();
    t.feed("G1 X10 Y0 Z10 I0 J0.5 K0.866", 3, out);  // leaves toward azimuth 90: C turns first
    const std::size_t C = std::size_t(m.joint_index('C')), B = std::size_t(m.joint_index('B'));
    double travel_c = 0, travel_b = 0;
    int lines = 0;
    for (const auto& l : lines_of(out)) {
        std::vector<double> cur = q;
        if (!apply_line(m, l, cur, nullptr, nullptr)) continue;
        ++lines;
        travel_c += std::abs(cur[C] - q[C]);
        travel_b += std::abs(cur[B] - q[B]);
        q = cur;
    }
    t.finish(out);
    REQUIRE(lines >= 2);
    REQUIRE(travel_c > 45);  // the turn
    const std::string json = report.json();
    const auto at = json.find("\"rotary_travel_deg\"");
    REQUIRE(at != std::string::npos);
    auto value = [&](char joint) {
        const auto p = json.find(std::string("\"") + joint + "\": ", at);
        REQUIRE(p != std::string::npos);
        return std::stod(json.substr(p + 5));
    };
    CHECK(std::abs(value('C') - travel_c) < 0.01);
    CHECK(std::abs(value('B') - travel_b) < 0.01);
}

namespace {

// A translated move's joint lines from `fw`: rotary travel, time under the firmware's feed rule
// (minutes), and the worst tip and axis deviation of the printed path, densely, against the
// programmed move a -> b (axis on its great circle).

struct Walked {
    double travel = 0, minutes = 0, tip = 0, angle = 0;
};
Walked walk(const Machine& m, const Kinematics& k, const std::string& out, std::vector<double>& fw, const Pose& a, const Pose& b, double& f) {
    Walked w;
    for (const auto& l : lines_of(out)) {
        std::vector<double> cur = fw;
        double e = 0;
        if (!apply_line(m, l, cur, &e, &f)) continue;
        for (std::size_t j = 0; j < cur.size(); ++j)
            if (m.joints[j].rotary) w.travel += std::abs(cur[j] - fw[j]);
        w.minutes += firmware_length(m, fw, cur) / f;
        for (int s = 1; s < 200; ++s) {
            std::vector<double> qq(cur.size());
            for (std::size_t j = 0; j < qq.size(); ++j) qq[j] = fw[j] + (cur[j] - fw[j]) * s / 200.0;
            const Pose p = k.forward(qq);
            w.tip = std::max(w.tip, seg_dist(p.tip, a.tip, b.tip));
            // The nearest point of the great-circle arc a -> b to the printed axis.
            w.angle = std::max(w.angle, arc_distance(p.axis, a.axis, b.axis));
        }
        fw = cur;
    }
    return w;
}

// The least rotary travel any way can have (brute force): the nearest of every solution of the
// end pose, each branch on every turn within two, to the start joints.
double least_travel(const Machine& m, const Kinematics& k, const std::vector<double>& q0, const Eigen::Vector3d& axis) {
    const auto sol = k.orientation_solutions(axis);
    const auto& rot = k.rotary_joints();
    double best = 1e300;
    for (int b = 0; b < sol.count; ++b)
        for (int t0 = -2; t0 <= 2; ++t0)
            for (int t1 = -2; t1 <= 2; ++t1) {
                double d = 0;
                bool ok = true;
                for (std::size_t n = 0; n < rot.size(); ++n) {
                    const Joint& J = m.joints[std::size_t(rot[n])];
                    const double v = sol.angle[b][n] + 360.0 * (n == 0 ? t0 : t1);
                    if (std::isnan(v)) continue;
                    if (v < J.min || v > J.max) ok = false;
                    d += std::abs(v - q0[std::size_t(rot[n])]);
                }
                if (ok) best = std::min(best, d);
            }
    return best;
}

}  // namespace

TEST_CASE("across the pole: a printed move passing 0.11 degrees from vertical turns B through zero, not the table round") {
    const Machine m = load("koc5");
    const Kinematics k(m);
    DeviationReport report("t.gcode", "koc5", m.motion.tolerance, m.motion.angle_tolerance);
    TranslatorOptions o;
    o.report = &report;
    Translator t(k, o);
    std::string out;
    for (const char* l : {"G43.5", "M83", "G1 X10 Y0 Z0 I0.03 J0.002 K1 F1500"}) t.feed(l, 1, out);
    std::vector<double> fw = t.joints();
    const std::vector<double> q0 = fw;
    const Pose a = t.pose();
    out.clear();
    t.feed("G1 X10.85 Y0 Z0 I-0.03 J0.002 K1 E0.04", 4, out);
    const Pose b = t.pose();
    double f = 1500;
    const Walked w = walk(m, k, out, fw, a, b, f);
    const double least = least_travel(m, k, q0, b.axis);
    const std::size_t B = std::size_t(m.joint_index('B'));
    MESSAGE("pole move: rotary travel " << w.travel << " deg (least possible " << least << "), " << w.minutes * 60 << " s, tip "
                                        << w.tip << " mm, axis " << w.angle << " deg");
    CHECK(q0[B] * fw[B] < 0);                  // B changed sign: the other branch
    CHECK(w.travel <= least + 0.01);           // the least turning there is
    // As long as the programmed feed or the rotary axes' own speed limits make it (0.85 mm at
    // 1500 mm/min is 0.034 s; C 7.6 degrees at 3600 deg/min 0.127 s), not the 2.9 s of a half turn.
    double need = 0.85 / 1500;
    for (std::size_t j = 0; j < fw.size(); ++j)
        if (m.joints[j].max_feed > 0) need = std::max(need, std::abs(fw[j] - q0[j]) / m.joints[j].max_feed);
    CHECK(w.minutes <= need * 1.01);
    CHECK(w.tip <= m.motion.tolerance + 1e-3); // printed joints: rounding included
    CHECK(w.angle <= m.motion.angle_tolerance);
    const std::string json = report.json();
    CHECK(contains(json, "\"pole_crossings\": 1"));
    CHECK(contains(json, "\"half_turns\": 0"));
}

TEST_CASE("across the pole: a helix and random near-pole moves turn the rotaries no more than the least possible") {
    const Machine m = load("koc5");
    const Kinematics k(m);
    for (const bool helix : {true, false}) {
        CAPTURE(helix);
        Translator t(k, {});
        std::string out;
        t.feed("G43.5", 1, out);
        t.feed("M83", 2, out);
        std::mt19937 rng(7);
        std::uniform_real_distribution<double> U(-1, 1);
        std::vector<double> fw = t.joints();
        double f = 1500;
        double travel = 0, least_sum = 0, minutes = 0, worst_tip = 0, worst_angle = 0;
        int near_pole = 0;
        Eigen::Vector3d prev_axis(0, 0, 1);
        for (int i = 0; i < 400; ++i) {
            Eigen::Vector3d tip, axis;
            if (helix) {
                // A helix whose tool tilt passes through zero and back (a wobbling spiral vase).
                const double s = i * 0.02;
                const double tilt = rad(3 * std::sin(s * 1.5)), az = s * 0.7;
                tip = {20 * std::cos(s), 20 * std::sin(s), 1 + 0.01 * i};
                axis = {std::sin(tilt) * std::cos(az), std::sin(tilt) * std::sin(az), std::cos(tilt)};
            } else {
                // From the current axis to the far side of vertical, a little off the azimuth
                // opposite: the great circle passes close by the pole (or the move leaves the pole).
                const Eigen::Vector3d now = t.pose().axis;
                const double az = std::atan2(now.y(), now.x()) + kPi + 0.3 * U(rng), tilt = rad(0.5 + 2 * std::abs(U(rng)));
                tip = {20 * U(rng), 20 * U(rng), 1 + std::abs(U(rng))};
                axis = {std::sin(tilt) * std::cos(az), std::sin(tilt) * std::sin(az), std::cos(tilt)};
            }
            const std::string line = "G1 X" + num(tip.x()) + " Y" + num(tip.y()) + " Z" + num(tip.z()) + " I" + num(axis.x(), 9) +
                                     " J" + num(axis.y(), 9) + " K" + num(axis.z(), 9) + (i == 0 ? " F1500" : " E0.01");
            const Pose a = t.pose();
            const std::vector<double> q0 = fw;
            out.clear();
            REQUIRE_NOTHROW(t.feed(line, std::uint64_t(i + 3), out));
            const Walked w = walk(m, k, out, fw, a, t.pose(), f);
            if (i == 0) continue;
            worst_tip = std::max(worst_tip, w.tip);
            worst_angle = std::max(worst_angle, w.angle);
            // Near the pole: the axis's great circle passes within 1 degree of vertical.
            const Eigen::Vector3d n = a.axis.cross(t.pose().axis);
            bool passes = false;
            if (n.norm() > 1e-9) {
                const Eigen::Vector3d nn = n.normalized(), z = Eigen::Vector3d::UnitZ();
                const Eigen::Vector3d p = (z - z.dot(nn) * nn).normalized();  // the circle's point nearest vertical
                passes = std::asin(std::min(1.0, std::abs(nn.z()))) < rad(0.25) && a.axis.cross(p).dot(nn) >= 0 &&
                         p.cross(t.pose().axis).dot(nn) >= 0;
            }
            const double least = least_travel(m, k, q0, t.pose().axis);
            if (passes) {
                ++near_pole;
                CAPTURE(line);
                CHECK(w.travel <= least + 1.0);
            }
            travel += w.travel;
            least_sum += least;
            minutes += w.minutes;
            prev_axis = axis;
        }
        MESSAGE(std::string(helix ? "helix" : "random near-pole moves") << ": rotary travel " << travel << " deg (least possible " << least_sum << "), "
                                                              << minutes * 60 << " s, " << near_pole << " moves near the pole, worst tip "
                                                              << worst_tip << " mm, axis " << worst_angle << " deg");
        CHECK(near_pole >= (helix ? 2 : 200));
        CHECK(worst_tip <= m.motion.tolerance + 1e-3);
        CHECK(worst_angle <= m.motion.angle_tolerance);
    }
}

TEST_CASE("near the pole over many short moves: the turntable turns only as much as the path outside the pole region needs") {
    // koc5's tool axis traces a small circle (radius r, centre d from vertical) over 1700 short
    // moves (0.013 degrees of axis each) along a helix: twice it passes the pole, 0.05 degrees off
    // it, or through it. Following the axis's azimuth there turns the table by half a turn for
    // each pass, however short the moves; within the angle tolerance it need not.
    const Machine m = load("koc5");
    const Kinematics k(m);
    const double atol = m.motion.angle_tolerance;
    const double region = 2 * atol;  // the pole region (see the planner): ends exact outside it
    const std::size_t C = std::size_t(m.joint_index('C'));
    for (const double miss : {0.05, 0.0}) {
        CAPTURE(miss);
        DeviationReport report("t.gcode", "koc5", m.motion.tolerance, atol);
        TranslatorOptions o;
        o.report = &report;
        Translator t(k, o);
        // Without a report the planner checks each passage's joint-linear turn on fewer points
        // and clears the rest by a bound: the same verdicts, so the same output.
        Translator plain(k, {});
        std::string out, all, plain_out;
        t.feed("G43.5", 1, out);
        t.feed("M83", 2, out);
        plain.feed("G43.5", 1, plain_out);
        plain.feed("M83", 2, plain_out);
        all = out;
        std::vector<double> fw = t.joints();
        const double d = rad(2.0), r = rad(2.0 - miss);
        double travel_c = 0, worst_tip = 0, worst_angle = 0, least_tilt = 1e9;
        // The reference: the azimuth's turns where the axis is outside the region (an exact
        // solution there, either branch: C or C + 180 with -B, eq. 11), and across each passage
        // through the region the least turn from the last exact end before it to the first after.
        double ref_c = std::nan(""), ref_travel = 0;
        for (int i = 0; i < 1700; ++i) {
            const double s = i * 0.005, ph = s * 1.3;
            const double ax = d + r * std::cos(ph), ay = r * std::sin(ph);
            const double tilt = std::hypot(ax, ay), az = std::atan2(ay, ax);
            const Eigen::Vector3d axis(std::sin(tilt) * std::cos(az), std::sin(tilt) * std::sin(az), std::cos(tilt));
            const std::string line = "G1 X" + num(20 * std::cos(s)) + " Y" + num(20 * std::sin(s)) + " Z" + num(1 + 0.0005 * i) + " I" +
                                     num(axis.x(), 9) + " J" + num(axis.y(), 9) + " K" + num(axis.z(), 9) + (i == 0 ? " F1500" : " E0.01");
            const Pose a = t.pose();
            out.clear();
            REQUIRE_NOTHROW(t.feed(line, std::uint64_t(i + 3), out));
            REQUIRE_NOTHROW(plain.feed(line, std::uint64_t(i + 3), plain_out));
            all += out;
            const Pose b = t.pose();
            for (const auto& l : lines_of(out)) {
                std::vector<double> cur = fw;
                if (!apply_line(m, l, cur, nullptr, nullptr)) continue;
                if (i > 0) {
                    travel_c += std::abs(cur[C] - fw[C]);
                    for (int u = 0; u <= 50; ++u) {
                        std::vector<double> qq(cur.size());
                        for (std::size_t j = 0; j < qq.size(); ++j) qq[j] = fw[j] + (cur[j] - fw[j]) * u / 50.0;
                        const Pose p = k.forward(qq);
                        worst_tip = std::max(worst_tip, seg_dist(p.tip, a.tip, b.tip));
                        worst_angle = std::max(worst_angle, arc_distance(p.axis, a.axis, b.axis));
                    }
                }
                fw = cur;
            }
            least_tilt = std::min(least_tilt, tilt * 180 / kPi);
            if (tilt * 180 / kPi >= region) {
                const double exact = std::atan2(-axis.y(), -axis.x()) * 180 / kPi;  // eq. 11 with B > 0
                if (std::isnan(ref_c)) ref_c = exact;
                double step = std::remainder(exact - ref_c, 180.0);  // either branch
                ref_travel += i > 0 ? std::abs(step) : 0.0;
                ref_c += step;
            }
        }
        out.clear();
        t.finish(out);
        all += out;
        plain.finish(plain_out);
        CHECK(all == plain_out);
        const std::string json = report.json();
        MESSAGE("pole passage missing by " << miss << " deg: C travel " << travel_c << " deg (outside the pole region "
                                           << ref_travel << "), worst tip " << worst_tip << " mm, axis " << worst_angle << " deg");
        CHECK(least_tilt <= miss + 0.01);
        CHECK(worst_tip <= m.motion.tolerance + kPrintSlack);
        CHECK(worst_angle <= atol);
        // Two passages (the path ends outside the region), each turning no more than the reference
        // needs, give or take a degree.
        CHECK(travel_c <= ref_travel + 2.0);
    }
}

// ---- re-zero: after a G92 the table turns as programmed ------------------------------------

namespace {

// What the firmware does with translated text, replayed by helpers.hpp's tracker as Marlin reads
// it: a G0/G1 turns a joint from where the firmware holds it to the value written; a G92 renames
// where the joint is and turns nothing. Physical turns of joint `j`, and the time at the F written.
struct Turns {
    double net = 0, path = 0, minutes = 0;
    int renames = 0;
};
void replay(const Machine& m, const std::string& text, std::size_t j, std::vector<double>& fw, double& f, Turns& t) {
    for (const auto& l : lines_of(text)) {
        std::vector<double> cur = fw;
        apply_joint_lines(m, l, cur);
        if (l.rfind("G92 ", 0) == 0) {
            if (words_of(l).count(m.joints[j].output)) ++t.renames;
        } else if (l.rfind("G0 ", 0) == 0 || l.rfind("G1 ", 0) == 0) {
            const auto w = words_of(l);
            if (w.count('F')) f = w.at('F');
            t.net += cur[j] - fw[j];
            t.path += std::abs(cur[j] - fw[j]);
            if (f > 0) t.minutes += firmware_length(m, fw, cur) / f;
        }
        fw = cur;
    }
}

double json_number(const std::string& json, const std::string& key) {
    const auto p = json.find("\"" + key + "\": ");
    REQUIRE(p != std::string::npos);
    return std::stod(json.substr(p + key.size() + 4));
}

enum class Form { Gcode, Apt, Waypoints };

struct Run {
    std::string out;
    Turns turns;
};

// Translates `lines` on koc5 (C re-zeroed beyond 1800 degrees) and replays the output. Without the
// look-back each line's physical C turn is checked against `turn` (NaN: not checked; by size
// only when `by_size`, for the forms that program a tool axis, whose shortest turn is the
// reference); the report's C travel and time are checked against the replay either way.
Run translate_turns(const std::vector<std::string>& lines, const std::vector<double>& turn, bool by_size, Form form, bool segment,
                    std::size_t lookback, std::optional<OrientationMode> mode) {
    REQUIRE(lines.size() == turn.size());
    Machine m = load("koc5");
    const std::size_t C = std::size_t(m.joint_index('C'));
    REQUIRE(m.joints[C].rezero_beyond == 1800);
    m.motion.segment = segment;
    const Kinematics k(m);
    DeviationReport report("t", "koc5", m.motion.tolerance, m.motion.angle_tolerance);
    TranslatorOptions o;
    o.report = &report;
    o.start_mode = mode;
    Translator t(k, o);
    t.set_lookback(lookback);
    FrontOptions fo{form == Form::Apt ? InputFormat::Apt : form == Form::Waypoints ? InputFormat::Waypoints : InputFormat::GCode};
    InputFront front(t, fo);
    std::vector<double> fw = t.joints();
    double f = 0;
    Run run;
    int checked = 0;
    for (std::size_t i = 0; i < lines.size(); ++i) {
        std::string o1;
        front.feed(lines[i], i + 1, o1);
        run.out += o1;
        Turns line;
        replay(m, o1, C, fw, f, line);
        run.turns.net += line.net, run.turns.path += line.path, run.turns.minutes += line.minutes, run.turns.renames += line.renames;
        if (std::isnan(turn[i]) || lookback > 0) continue;
        CAPTURE(lines[i]);
        CAPTURE(o1);
        ++checked;
        // The line's turn is the programmed one (C printed to 3 decimals), made monotonically.
        if (by_size) CHECK(std::abs(std::abs(line.net) - std::abs(turn[i])) < 2e-3);
        else CHECK(std::abs(line.net - turn[i]) < 2e-3);
        CHECK(std::abs(line.path - std::abs(line.net)) < 2e-3);
    }
    std::string rest;
    front.finish(lines.size(), rest);
    t.finish(rest);
    run.out += rest;
    replay(m, rest, C, fw, f, run.turns);
    if (lookback == 0) CHECK(checked > 0);
    // The report measured the same motion: C's travel (from the joints before they are printed to
    // 3 decimals) and the time (before F is printed to 0.1).
    const std::string json = report.json();
    CAPTURE(json);
    CHECK(json_number(json, "rezeros") == run.turns.renames);
    const auto travel = json.find("\"rotary_travel_deg\"");
    REQUIRE(travel != std::string::npos);
    CHECK(std::abs(json_number(json.substr(travel), "C") - run.turns.path) < 1e-3 * double(lines.size()));
    CHECK(json_number(json, "estimated_minutes") == doctest::Approx(run.turns.minutes).epsilon(2e-3));
    return run;
}

// Each of `lines` turns the table as programmed, with and without splitting; the look-back (which
// holds lines, so checked as a whole) writes the same turns.
std::string check_turns(const std::vector<std::string>& lines, const std::vector<double>& turn, bool by_size, Form form,
                        std::optional<OrientationMode> mode = std::nullopt) {
    std::string out;
    for (const bool segment : {true, false}) {
        CAPTURE(segment);
        const Run plain = translate_turns(lines, turn, by_size, form, segment, 0, mode);
        const Run held = translate_turns(lines, turn, by_size, form, segment, Translator::kDefaultLookback, mode);
        MESSAGE("segment " << segment << ": C turned " << plain.turns.path << " deg, " << plain.turns.renames << " re-zeros, "
                           << plain.turns.minutes * 60 << " s; with the look-back " << held.turns.path << " deg");
        CHECK(plain.turns.renames >= 2);
        CHECK(held.turns.renames == plain.turns.renames);
        CHECK(std::abs(held.turns.path - plain.turns.path) < 1e-6);
        CHECK(std::abs(held.turns.net - plain.turns.net) < 1e-6);
        if (segment) out = plain.out;
    }
    return out;
}

// A tool tilted 30 degrees from vertical at 15 i degrees about Z (C turns 15 per step), at a
// point of a circle of radius 20: x y z i j k, each before `sep[n]`.
std::string tilted(int i, const std::vector<std::string>& sep) {
    const double az = rad(15.0 * i), tilt = rad(30);
    const double v[6] = {20 * std::cos(az), 20 * std::sin(az), 5, std::sin(tilt) * std::cos(az), std::sin(tilt) * std::sin(az), std::cos(tilt)};
    std::string s;
    for (int n = 0; n < 6; ++n) s += sep[std::size_t(n)] + num(v[n], n < 3 ? 6 : 9);
    return s;
}

}  // namespace

TEST_CASE("re-zero: after G92 C-160 from 2000 a programmed C2010 turns the table 10 degrees, not 2170") {
    const std::string out = check_turns({"G28", "G1 X0 Y0 Z10 C1000 F1000", "G1 X0 Y0 Z10 C2000", "G1 X1 C2010", "G1 X0 C4000", "G1 X1 C4010"},
                                        {NAN, 1000, 1000, 10, 1990, 10}, false, Form::Gcode, OrientationMode::Angles);
    CHECK(contains(out, "G1 C2000 F3600\nG92 C-160\n"));
}

TEST_CASE("re-zero: the program's angles go on across a switch to G43.5 and back; a G92 on C sets them afresh") {
    // Entering G43.4 the programmed angles are the joints as they are, but for the turns the
    // re-zeros took off: those are the firmware's business.
    check_turns({"G43.4", "G1 X0 Y0 Z10 B20 C1000 F1000", "G1 X0 Y0 Z10 C2000", "G43.5", "G1 X1", "G43.4", "G1 X1 C2010", "G1 X0 C4000",
                 "G43.5", "G1 X1", "G43.4", "G1 X0 C4010"},
                {NAN, 1000, 1000, NAN, 0, NAN, 10, 1990, NAN, 0, NAN, 10}, false, Form::Gcode);
    // A G92 on C says where the table is in the program's angles: they count from it again.
    const Machine m = load("koc5");
    const Kinematics k(m);
    Translator t(k, {});
    std::string out;
    std::uint64_t n = 0;
    for (const char* l : {"G43.4", "G1 X0 Y0 Z10 B20 C1000 F1000", "G1 X0 Y0 Z10 C2000", "G92 C0", "G1 X1 C10", "G28", "G43.4",
                          "G1 X0 Y0 Z10 B20 C30"})
        t.feed(l, ++n, out);
    CAPTURE(out);
    CHECK(contains(out, "G92 C-160\nG92 C0\n"));
    CHECK(contains(out, " C10 "));
    CHECK(contains(out, "G28\n"));
    CHECK(contains(out, " C30 "));
    std::vector<double> fw = m.home_joints();
    double f = 0;
    Turns turns;
    replay(m, out.substr(0, out.find("G28\n")), std::size_t(m.joint_index('C')), fw, f, turns);  // to the homing
    CHECK(std::abs(turns.path - (2000 + 10)) < 1e-6);
}

TEST_CASE("re-zero under G43.4: each line turns C by its programmed change, printed, travel, arcs, relative angles") {
    // C 25 degrees on per line to about 5000, every 4th line a travel (re-zeroed there past 1800);
    // an arc and a G91 stretch after the first re-zero.
    std::vector<std::string> lines = {"G43.4", "M83", "G1 X10 Y0 Z10 B20 C0 F1000"};
    std::vector<double> turn = {NAN, NAN, 0};
    double c = 0;
    for (int i = 1; i <= 200; ++i) {
        const double a = rad(5.0 * i);
        if (i == 100) {
            // Half a circle and a bit about the origin (radius 10) with C turned by 40 along it,
            // then straight back with C turned back by 30.
            lines.push_back("G3 X" + num(10 * std::cos(a + kPi)) + " Y" + num(10 * std::sin(a + kPi)) + " I" + num(-10 * std::cos(a - rad(5))) +
                            " J" + num(-10 * std::sin(a - rad(5))) + " C" + num(c + 40) + " E0.5");
            turn.push_back(40), c += 40;
            lines.push_back("G1 X" + num(10 * std::cos(a)) + " Y" + num(10 * std::sin(a)) + " C" + num(c - 30));
            turn.push_back(-30), c -= 30;
            continue;
        }
        if (i >= 150 && i < 160) {
            lines.push_back(i == 150 ? "G91" : "G1 C25" + std::string(i % 4 ? " E0.02" : ""));
            turn.push_back(i == 150 ? NAN : 25);
            if (i > 150) c += 25;
            if (i == 159) lines.push_back("G90"), turn.push_back(NAN);
            continue;
        }
        c += 25;
        lines.push_back("G1 X" + num(10 * std::cos(a)) + " Y" + num(10 * std::sin(a)) + " C" + num(c) + (i % 4 ? " E0.02" : ""));
        turn.push_back(25);
    }
    check_turns(lines, turn, false, Form::Gcode);
}

TEST_CASE("re-zero under G43.5, CL data, waypoints and G68.2 planes: the table turns the tool axis's 15 degrees per line") {
    const int n = 300;  // 12.5 turns
    std::vector<std::string> lines;
    std::vector<double> turn;
    SUBCASE("G43.5") {
        lines = {"G43.5", "M83"}, turn = {NAN, NAN};
        for (int i = 0; i < n; ++i) {
            lines.push_back("G1" + tilted(i, {" X", " Y", " Z", " I", " J", " K"}) + (i % 8 ? " E0.01" : "") + (i == 0 ? " F1200" : ""));
            turn.push_back(i == 0 ? NAN : 15);
        }
        check_turns(lines, turn, true, Form::Gcode);
    }
    SUBCASE("CL data") {
        lines = {"UNITS/MM", "FEDRAT/MMPM,1200"}, turn = {NAN, NAN};
        for (int i = 0; i < n; ++i) {
            lines.push_back("GOTO/" + tilted(i, {"", ",", ",", ",", ",", ","}));
            turn.push_back(i == 0 ? NAN : 15);
        }
        check_turns(lines, turn, true, Form::Apt);
    }
    SUBCASE("waypoints") {
        for (int i = 0; i < n; ++i) {
            lines.push_back(tilted(i, {"", " ", " ", " ", " ", " "}));
            turn.push_back(i == 0 ? NAN : 15);
        }
        check_turns(lines, turn, true, Form::Waypoints);
    }
    SUBCASE("G68.2 planes") {
        // A plane tilted 30 degrees, turned 15 degrees about Z per plane: G53.1 turns the tool
        // onto it (a travel, re-zeroed after it), a line is printed in it and the tip returns.
        lines = {"G43.4", "M83", "G1 X0 Y0 Z5 B0 C0 F1200"}, turn = {NAN, NAN, NAN};
        for (int i = 0; i < n; ++i) {
            for (const std::string& l : {"G68.2 X0 Y0 Z5 I" + num(std::fmod(15.0 * i, 360.0), 3) + " J30", std::string("G53.1"),
                                         std::string("G1 X5 Y0 Z0 E0.1"), std::string("G1 X0 Y0 Z0"), std::string("G69")})
                lines.push_back(l);
            for (const double v : {double(NAN), i == 0 ? double(NAN) : 15.0, 0.0, 0.0, double(NAN)}) turn.push_back(v);
        }
        check_turns(lines, turn, true, Form::Gcode);
    }
}

TEST_CASE("re-zero: the output read back through --inverse and translated again turns the table as the first translation did") {
    Machine m = load("koc5");
    const Kinematics k(m);
    const std::size_t C = std::size_t(m.joint_index('C'));
    std::vector<std::string> lines = {"G43.4", "M83", "G1 X10 Y0 Z10 B20 C0 F1000"};
    for (int i = 1; i <= 200; ++i)
        lines.push_back("G1 X" + num(10 * std::cos(rad(5.0 * i))) + " Y" + num(10 * std::sin(rad(5.0 * i))) + " C" + num(25.0 * i) +
                        (i % 4 ? " E0.02" : ""));
    auto run = [&](const std::vector<std::string>& in, TranslatorOptions o) {
        Translator t(k, o);
        std::string out;
        std::uint64_t n = 0;
        for (const auto& l : in) t.feed(l, ++n, out);
        t.finish(out);
        return out;
    };
    const std::string joints = run(lines, {});
    TranslatorOptions inv;
    inv.inverse = true;
    for (const OrientationMode form : {OrientationMode::Angles, OrientationMode::Vector}) {
        CAPTURE(int(form));
        inv.preview_form = form;
        const std::string tool = run(lines_of(joints), inv);
        CHECK(contains(tool, "G92 C"));
        TranslatorOptions back;
        back.start_mode = form;  // the tool-space file is written without the mode word
        const std::string again = run(lines_of(tool), back);
        std::vector<double> fw0 = m.home_joints(), fw1 = fw0;
        double f0 = 0, f1 = 0;
        Turns first, second;
        replay(m, joints, C, fw0, f0, first);
        replay(m, again, C, fw1, f1, second);
        MESSAGE("C: " << first.path << " deg, " << first.renames << " re-zeros; read back and translated again: " << second.path << " deg, "
                      << second.renames << " re-zeros");
        CHECK(first.renames >= 2);
        CHECK(std::abs(first.path - 25.0 * 200) < 0.1);
        CHECK(std::abs(second.path - first.path) < 0.1);
        CHECK(std::abs(second.net - first.net) < 0.1);
    }
}

TEST_CASE("the pole passage's verdict without a report (fewer points, a bound between them) is the one with every point measured") {
    // With a report the planner measures every point of a passage's joint-linear turn; without
    // one it halves the turn from its ends until a bound clears each part. The same verdicts give
    // the same output: tool axes tracing small circles past the pole (through it, and missing
    // it by up to 1.5 degrees), in steps from a tenth of the angle tolerance to twice it, on every
    // shipped machine that holds its turntable near the pole.
    int machines = 0;
    for (const auto& [name, path] : bundled_machines()) {
        Machine m = load_machine(path);
        m.motion.tolerance = 0.01;  // the benchmark's: many moves split, so ends as printed
        const Kinematics k(m);
        if (k.rotary_joints().size() != 2 || !k.has_flip() || !m.motion.segment) continue;
        // A machine with an absent linear joint (core-rtheta's missing Y) reaches only the tool
        // axes in its own plane: these small circles round the pole are beyond it.
        bool absent = false;
        for (const Joint& j : m.joints) absent = absent || j.absent;
        if (absent) continue;
        ++machines;
        CAPTURE_BINDING(name);
        const double atol = m.motion.angle_tolerance;
        int lines = 0;
        // Round the tip where the linear joints are mid-range (rotaries at zero).
        std::vector<double> mid(m.joints.size(), 0.0);
        for (std::size_t j = 0; j < mid.size(); ++j)
            if (!m.joints[j].rotary && m.joints[j].bounded()) mid[j] = 0.5 * (m.joints[j].min + m.joints[j].max);
        const Eigen::Vector3d centre = k.forward(mid).tip;
        // The same G43.5 program through a translator with a report (every point of a passage
        // measured) and one without; their outputs a and b.
        struct Both {
            DeviationReport report;
            Translator measured, plain;
            std::string a, b;
            static TranslatorOptions reporting(DeviationReport* r) {
                TranslatorOptions o;
                o.report = r;
                return o;
            }
            Both(const Kinematics& k, const std::string& name, double tol, double atol)
                : report("t.gcode", name, tol, atol), measured(k, reporting(&report)), plain(k, {}) {
                for (Translator* t : {&measured, &plain}) {
                    std::string& out = t == &measured ? a : b;
                    t->feed("G43.5", 1, out);
                    t->feed("M83", 2, out);
                }
            }
            // One line through both: the same words, or the same error (a joint limit may end the
            // path, rw2's A); false once either has refused a line.
            bool feed(const std::string& line, std::uint64_t no) {
                std::string why_a, why_b;
                try {
                    measured.feed(line, no, a);
                } catch (const std::exception& e) {
                    why_a = e.what();
                }
                try {
                    plain.feed(line, no, b);
                } catch (const std::exception& e) {
                    why_b = e.what();
                }
                CHECK(why_a == why_b);
                return why_a.empty() && why_b.empty();
            }
            void finish() {
                measured.finish(a);
                plain.finish(b);
                CHECK(a == b);
            }
        };
        for (const double miss : {0.0, 0.01, 0.05, 0.3, 1.5})
            for (const double step : {0.1, 0.5, 2.0}) {

                CAPTURE(miss);
                CAPTURE(step);
                Both both(k, name, m.motion.tolerance, atol);
                const double d = rad(3.0), r = rad(3.0 - miss), dphi = rad(step * atol) / r;
                // Half the circle, the pole passage in its middle.
                const int n = int(kPi / dphi) + 1;
                for (int i = 0; i < n; ++i) {
                    const double ph = kPi / 2 + i * dphi, s = i * 0.004;
                    const double ax = d + r * std::cos(ph), ay = r * std::sin(ph);
                    const double tilt = std::hypot(ax, ay), az = std::atan2(ay, ax);
                    const Eigen::Vector3d axis(std::sin(tilt) * std::cos(az), std::sin(tilt) * std::sin(az), std::cos(tilt));
                    const std::string line = "G1 X" + num(centre.x() + 5 * std::cos(s)) + " Y" + num(centre.y() + 5 * std::sin(s)) +
                                             " Z" + num(centre.z() + 0.0005 * i) +
                                             " I" + num(axis.x(), 9) + " J" + num(axis.y(), 9) + " K" + num(axis.z(), 9) +
                                             (i == 0 ? " F1500" : " E0.01");
                    if (!both.feed(line, std::uint64_t(i + 3))) break;
                    ++lines;
                }
                both.finish();
            }
        // The benchmark's helix (bench_translate), round the machine's middle: its short moves end
        // on joints as printed, so no start is exact and each move's turn is checked; twice a
        // turn its azimuth jumps by 60 degrees, a turn whose joint-linear path leaves the great
        // circle in its middle only. 300 lines round each of twelve jumps, at tilts of either sign.
        for (int jump = 1; jump <= 12; ++jump) {
            CAPTURE(jump);
            Both both(k, name, m.motion.tolerance, atol);
            const long first = long(jump * 523.6) - 150;
            for (long i = first; i < first + 300; ++i) {
                const double t = double(i) * 0.01;
                const double x = 30 * std::cos(t), y = 30 * std::sin(t), z = 1 + 0.0002 * double(i);
                const double tilt = rad(20 * std::sin(t * 0.1)), az = rad(std::fmod(t * 57.29577951308232, 300.0) - 150.0);
                char line[160];
                std::snprintf(line, sizeof line, "G1 X%.3f Y%.3f Z%.3f I%.6f J%.6f K%.6f E%.5f F1800", centre.x() + x, centre.y() + y,
                              centre.z() + z, std::sin(tilt) * std::sin(az), std::sin(tilt) * std::cos(az), std::cos(tilt), 0.0123);
                if (!both.feed(line, std::uint64_t(i + 3))) break;
                ++lines;
            }
            both.finish();
        }
        // voron-xyzac's Y travel (to 109.5) ends its loops sooner (920 lines there).
        CHECK(lines > 500);
    }
    CHECK(machines >= 2);
}

TEST_CASE("the split's ends as printed: its one-pass rounding is to_units' over the power of ten, bit for bit, any value") {
    // PlannedMove in joint space: split rounds both ends and stops there (one piece, split_joints()
    // is the end as printed). Moves chained from the last end (the one-pass path) and not.
    for (const std::string name : {"rw2", "pentarod", "koc5", "wpi5", "xyzac-trt"}) {
        CAPTURE(name);
        const Machine m = load(name);
        const Kinematics k(m);
        JointEmitter em(m);
        MotionStage stage(k, em);
        const std::size_t n = m.joints.size();
        std::mt19937 rng(std::hash<std::string>{}(name) & 0xffff);
        std::uniform_real_distribution<double> U(-1, 1);
        std::uniform_int_distribution<int> kind(0, 9);
        // Values about every rounding edge: small and large, halves of the last digit, near
        // to_units' limits (1e15 scaled, kMaxWritten) and past them.
        auto value = [&](int d) {
            const double p = std::pow(10.0, d);
            switch (kind(rng)) {
                case 0: return (std::round(U(rng) * 1e6) + 0.5) / p;
                case 1: return U(rng) * 1e3;
                case 2: return U(rng) * kMaxWritten;
                case 3: return kMaxWritten * (1 + 1e-3 * U(rng));
                case 4: return 0.5e15 / p * (1 + 1e-9 * U(rng));
                case 5: return U(rng) * 3e9;
                case 6: return -0.0;
                case 7: return std::nextafter((std::round(U(rng) * 1e4) + 0.5) / p, U(rng) * 2);
                default: return U(rng) * 400;
            }
        };
        std::vector<double> q0(n), q1(n), prev(n);
        const JointBits all = (JointBits(1) << n) - 1;
        std::string out;
        for (int i = 0; i < 20000; ++i) {
            for (std::size_t j = 0; j < n; ++j) {
                const int d = m.joints[j].rotary ? m.dialect.rotary_decimals : m.dialect.linear_decimals;
                q1[j] = value(d);
            }
            if (i % 5 == 4) q0 = q1;   // a move to where it is (no rotary turns)
            else if (i % 3 == 0) {
                for (std::size_t j = 0; j < n; ++j) q0[j] = value(m.joints[j].rotary ? m.dialect.rotary_decimals : m.dialect.linear_decimals);
            } else q0 = prev;          // from the last end (the usual case)
            PlannedMove mv;
            mv.mode = OrientationMode::Joints;
            set_joints(mv.q0, q0);
            set_joints(mv.q1, q1);
            mv.commanded = all;
            out.clear();
            try {
                stage.emit(mv, out);
            } catch (const std::exception&) {
                // A value the emitter cannot write: the split was made before.
            }
            prev = q1;
            REQUIRE(stage.split_params().size() == 1);
            const std::vector<double>& got = stage.split_joints();
            REQUIRE(got.size() == n);
            for (std::size_t j = 0; j < n; ++j) {
                const int d = m.joints[j].rotary ? m.dialect.rotary_decimals : m.dialect.linear_decimals;
                long long units = 0;
                const double want = to_units(q1[j], d, units) ? double(units) / std::pow(10.0, d) : q1[j];
                CAPTURE(q1[j]);
                CHECK(std::memcmp(&got[j], &want, sizeof want) == 0);
            }
        }
    }
}
