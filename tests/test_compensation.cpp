// SPDX-License-Identifier: GPL-3.0-or-later
// Error compensation against Andersons (Twente 2023): its tables reproduce its measurements, agree with its
// fitted eq. 4.7-4.9 within the scatter of the measurements, and undo exactly in --inverse.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <unistd.h>

#include "helpers.hpp"
#include "translators/machine/calibration.hpp"
#include "translators/pipeline/compensation.hpp"
#include "translators/error.hpp"
#include "translators/kinematics/kinematics.hpp"
#include "translators/machine/machine.hpp"
#include "translators/pipeline/translator.hpp"

using namespace xlate5;
using namespace xlate5::test;

namespace {

const std::string kDir = XLATE5_MACHINE_DIR_FOR_TESTS;

Machine rw2_measured() {
    Machine m = load_machine(kDir + "/rw2.toml", {{"la", 29.0}});
    load_compensation_file(kDir + "/compensation/rw2-andersons2023.toml", m);
    return m;
}

// Andersons' (Twente 2023) fitted error functions, eq. 4.7-4.9 (A in degrees, mm).
double ex(double a) { return 2 * std::cos(rad(a)) - 2; }
double ey(double a) { return -2 * std::sin(rad(a)); }
double ez(double a) { return -0.45 * std::sin(rad(a + 40)) + 0.29; }

}  // namespace

TEST_CASE("with la = 29 and table 4.1, the joints are table 4.1's measured X and Y") {
    const Machine m = rw2_measured();
    const Kinematics k(m);
    struct Row { double a, x, y; };
    // Table 4.1, "Measured" columns: where the tip really met the reference at (100, 100).
    const Row rows[] = {{-135, 82.29, 48.69}, {-90, 72.8, 69}, {-45, 80.29, 90.11}, {0, 100, 100},
                        {45, 121.11, 92.92}, {90, 131.2, 72.2}, {135, 123.91, 51.49}};
    for (const Row& r : rows) {
        CAPTURE(r.a);
        Translator t(k, {});
        std::string out;
        t.feed("G1 X100 Y100 Z10 A" + std::to_string(r.a) + " B0 F1200", 1, out);
        const auto w = words_of(lines_of(out).back());
        // The table prints its theoretical values to 2 decimals, so its measured = theoretical -
        // difference carries that rounding; the output has 3 decimals.
        CHECK(std::abs(w.at('X') - r.x) <= 0.0055);
        CHECK(std::abs(w.at('Y') - r.y) <= 0.0055);
    }
}

TEST_CASE("the tables agree with eq. 4.7-4.9 within the scatter of the measurements") {
    const Machine m = rw2_measured();
    REQUIRE(m.compensation.terms.size() == 3);
    double (*eq[3])(double) = {ex, ey, ez};
    const double amplitude[3] = {2, 2, 0.45};
    for (int i = 0; i < 3; ++i) {
        const CompensationTerm& t = m.compensation.terms[std::size_t(i)];
        CAPTURE(i);
        // Scatter: how far the measured points themselves lie from the fitted curve.
        double scatter = 0, step = 0;
        for (std::size_t p = 0; p < t.angle.size(); ++p) {
            scatter = std::max(scatter, std::abs(t.error[p] - eq[i](t.angle[p])));
            if (p) step = std::max(step, t.angle[p] - t.angle[p - 1]);
        }
        // Between points a straight line can leave a sinusoid of this amplitude by at most this.
        const double chord = amplitude[i] * (1 - std::cos(rad(step / 2)));
        double worst = 0;
        for (double a = t.angle.front(); a <= t.angle.back(); a += 0.5) {
            double e = 0;
            REQUIRE(t.eval(a, e));
            worst = std::max(worst, std::abs(e - eq[i](a)));
        }
        MESSAGE("term " << i << ": scatter of the measurements " << scatter << " mm, table vs fitted curve at most " << worst << " mm");
        CHECK(worst <= scatter + chord + 1e-9);
        CHECK(scatter < (i == 2 ? 0.1 : 0.9));  // the published residuals: about 0.8 mm (X, Y), 0.05 mm (Z)
    }
}

TEST_CASE("a Fourier fit of table 4.2 recovers eq. 4.9 (with the table's sign flipped)") {
    const Machine m = rw2_measured();
    const CompensationTerm& z = m.compensation.terms[2];
    double residual = 0;
    const CompensationTerm f = fit_fourier(z.angle, z.error, 1, residual);
    // eq. 4.9: -0.45 sin(A + 40) + 0.29 = 0.29 - 0.45 sin 40 cos A - 0.45 cos 40 sin A.
    const double amp = std::hypot(f.cosines[0], f.sines[0]);
    const double phase = std::atan2(-f.cosines[0], -f.sines[0]) * 180 / kPi;
    CHECK(f.a0 == doctest::Approx(0.29).epsilon(0.06));
    CHECK(amp == doctest::Approx(0.45).epsilon(0.05));
    CHECK(std::abs(phase - 40) < 3);
    MESSAGE("one-harmonic fit of table 4.2: a0 " << f.a0 << ", amplitude " << amp << ", phase " << phase << " deg, residual " << residual);
    CHECK(residual < 0.1);  // the table's own scatter about eq. 4.9 is 0.09 mm
    double e = 0;
    CHECK(f.eval(60, e));
    CHECK(e == doctest::Approx(ez(60)).epsilon(0.2));
}

TEST_CASE("every emitted piece is compensated and --inverse undoes it exactly") {
    const Machine m = rw2_measured();
    const Kinematics k(m);
    Translator fwd(k, {});
    TranslatorOptions io;
    io.inverse = true;
    Translator inv(k, io);
    std::string out, back;
    const std::vector<std::string> in = {"G1 X100 Y100 Z10 A0 B0 F1200", "G1 X110 Y105 A60 B15", "G1 X95 Y120 A-100 B-20",
                                         "G1 X100 Y100 A150 B0"};
    std::uint64_t n = 0, nb = 0;
    for (const auto& l : in) {
        const Pose before = fwd.pose();
        std::string o;
        fwd.feed(l, ++n, o);
        const Pose after = fwd.pose();
        // Each piece, read back through the inverse, lies on the programmed line (the printed
        // joints are rounded to 3 decimals, and the tables correct only the nominal model).
        for (const auto& line : lines_of(o)) {
            std::string b;
            inv.feed(line, ++nb, b);
            if (line.rfind("G1", 0) != 0 || n == 1) continue;
            const Eigen::Vector3d p = inv.pose().tip, ab = after.tip - before.tip;
            const double tt = std::clamp((p - before.tip).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
            CHECK((before.tip + tt * ab - p).norm() < m.motion.tolerance + 0.003);
        }
        CHECK((inv.pose().tip - after.tip).norm() < 2e-3);
        for (std::size_t j = 0; j < m.joints.size(); ++j) CHECK(std::abs(inv.joints()[j] - fwd.joints()[j]) < 2e-3);
        out += o;
    }
    // And compensation really changed the output: the same file without it differs by table 4.1.
    Machine plain = load_machine(kDir + "/rw2.toml", {{"la", 29.0}});
    const Kinematics kp(plain);
    Translator t2(kp, {});
    std::string o2;
    t2.feed(in[0], 1, o2);
    o2.clear();
    t2.feed("G1 A90", 2, o2);
    Translator t3(k, {});
    std::string o3;
    t3.feed(in[0], 1, o3);
    o3.clear();
    t3.feed("G1 A90", 2, o3);
    // Where each output leaves X (a move's last piece names only the joints it changes).
    std::vector<double> q2(plain.joints.size(), 0.0), q3(m.joints.size(), 0.0);
    apply_joint_lines(plain, o2, q2);
    apply_joint_lines(m, o3, q3);
    CHECK(q2[0] - q3[0] == doctest::Approx(-2.20).epsilon(1e-6));  // X error at A = 90
}

TEST_CASE("outside a table: refused with the line, or clamped, as the file says") {
    Machine m = load_machine(kDir + "/rw2.toml");
    const std::string refuse = kDir + "/../build-test-comp-refuse.toml";
    {
        std::FILE* f = std::fopen(refuse.c_str(), "w");
        REQUIRE(f);
        std::fputs("[[compensation]]\njoint = \"X\"\nby = \"A\"\npoints = [[-45, 0.1], [45, -0.1]]\n", f);
        std::fclose(f);
    }
    load_compensation_file(refuse, m);
    const Kinematics k(m);
    Translator t(k, {});
    std::string out;
    t.feed("G92 A0", 1, out);  // A is at 0 (inside the table) rather than at its home switch
    t.feed("G1 X100 Y100 Z10 A0 B0 F1200", 1, out);
    try {
        t.feed("G1 A60", 7, out);
        FAIL("expected a refusal");
    } catch (const InputError& e) {
        CHECK(e.line() == 7);
        CHECK(contains(e.message(), "covers -45.000 .. 45.000"));
    }
    // Clamped: beyond the table the end value applies.
    {
        std::FILE* f = std::fopen(refuse.c_str(), "w");
        std::fputs("[[compensation]]\njoint = \"X\"\nby = \"A\"\noutside = \"clamp\"\npoints = [[-45, 0.1], [45, -0.1]]\n", f);
        std::fclose(f);
    }
    load_compensation_file(refuse, m);
    const Kinematics k2(m);
    Translator t2(k2, {});
    out.clear();
    t2.feed("G92 A0", 1, out);
    t2.feed("G1 X100 Y100 Z10 A0 B0 F1200", 1, out);
    CHECK_NOTHROW(t2.feed("G1 A60", 2, out));
    // A broken file names its line and key.
    {
        std::FILE* f = std::fopen(refuse.c_str(), "w");
        std::fputs("[[compensation]]\njoint = \"X\"\nby = \"Y\"\npoints = [[0, 0], [1, 1]]\n", f);
        std::fclose(f);
    }
    CHECK_THROWS_WITH_AS(load_compensation_file(refuse, m), doctest::Contains("compensation[0].by: expected a rotary joint"), MachineError);
    std::remove(refuse.c_str());
}

namespace {

// Independent reference for the tables below: the periodic table closed with its first point one
// turn on, the angle brought into that turn; the clamped one evaluated at the angle held to its ends.
double interpolate(std::vector<std::pair<double, double>> pts, double a, bool periodic) {
    if (periodic) {
        pts.push_back({pts.front().first + 360, pts.front().second});
        a -= 360 * std::floor((a - pts.front().first) / 360);
    } else {
        a = std::clamp(a, pts.front().first, pts.back().first);
    }
    for (std::size_t i = 1; i < pts.size(); ++i)
        if (a <= pts[i].first) return pts[i - 1].second + (a - pts[i - 1].first) / (pts[i].first - pts[i - 1].first) * (pts[i].second - pts[i - 1].second);
    return pts.back().second;
}

std::string table_text(const std::vector<std::pair<double, double>>& pts) {
    std::ostringstream s;
    s << "[";
    for (std::size_t i = 0; i < pts.size(); ++i) s << (i ? ", " : "") << "[" << pts[i].first << ", " << pts[i].second << "]";
    return s.str() + "]";
}

std::string translate_text(const Machine& m, const std::string& text, TranslatorOptions options) {
    const Kinematics k(m);
    Translator t(k, options);
    std::istringstream in(text);
    std::string line, out;
    std::uint64_t n = 0;
    while (std::getline(in, line)) t.feed(line, ++n, out);
    return out;
}

// Every G0/G1 line of a file with the modal value of each letter after it (from `home` at the
// start and after G28, where the firmware has them), and the E word the line carries (NaN if none).
struct Move {
    std::map<char, double> at;
    double e = std::nan("");
};
std::vector<Move> moves_of(const std::string& text, const std::map<char, double>& home) {
    std::vector<Move> moves;
    std::map<char, double> modal = home;
    std::istringstream in(text);
    std::string line;
    while (std::getline(in, line)) {
        if (auto c = line.find(';'); c != std::string::npos) line.resize(c);
        while (!line.empty() && (line.back() == '\r' || line.back() == ' ')) line.pop_back();
        if (line.rfind("G28", 0) == 0) modal = home;
        if (line.empty() || line[0] != 'G' || line.find_first_of(" ") == std::string::npos) continue;
        const auto w = words_of(line);
        if (w.at('G') != 0 && w.at('G') != 1) continue;
        Move m;
        for (const auto& [letter, value] : w)
            if (letter != 'G' && letter != 'F' && letter != 'E') modal[letter] = value;
        m.at = modal;
        if (w.count('E')) m.e = w.at('E');
        moves.push_back(m);
    }
    return moves;
}

double at(const Move& m, char letter) { return m.at.count(letter) ? m.at.at(letter) : std::nan(""); }

}  // namespace

TEST_CASE("compensation over a real file: S4's joint-space R-theta print on koc5, corrected by the tables and undone by --inverse" *
          doctest::skip(corpus_absent())) {
    // The corpus file turns B from -54 to 12 degrees and C through 4000 degrees, so the tables
    // are read all round, across the periodic seam and beyond the linear table's ends. The
    // tables are Andersons' (Twente 2023) table 4.1 X column re-targeted to koc5's C (no koc5 measurement
    // exists), and a made-up Z by B that clamps.
    const std::vector<std::pair<double, double>> x_by_c = {{-135, -2.80}, {-90, -1.80}, {-45, -0.80}, {0, 0.00}, {45, -0.60}, {90, -2.20}, {135, -3.40}};
    const std::vector<std::pair<double, double>> z_by_b = {{-30, 0.12}, {-10, 0.03}, {0, 0}, {10, -0.05}, {30, -0.2}};
    const std::string comp_path = (std::filesystem::temp_directory_path() / ("xlate5-koc5-comp-" + std::to_string(::getpid()) + ".toml")).string();
    std::ofstream(comp_path) << "[[compensation]]\njoint = \"X\"\nby = \"C\"\ninterpolation = \"periodic\"\npoints = " << table_text(x_by_c)
                             << "\n\n[[compensation]]\njoint = \"Z\"\nby = \"B\"\noutside = \"clamp\"\npoints = " << table_text(z_by_b) << "\n";
    const Machine plain = load_machine(kDir + "/koc5.toml");
    Machine comp = plain;
    load_compensation_file(comp_path, comp);
    std::filesystem::remove(comp_path);
    REQUIRE(comp.compensation.terms.size() == 2);

    std::ifstream f(corpus_dir() + "/s4/pi_3mm_side_paint_rtheta.gcode", std::ios::binary);
    REQUIRE(f);
    const std::string input((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
    TranslatorOptions joints;
    joints.start_mode = OrientationMode::Joints;
    const std::string out_plain = translate_text(plain, input, joints), out_comp = translate_text(comp, input, joints);
    TranslatorOptions inverse;
    inverse.inverse = true;
    const std::string preview = translate_text(comp, out_comp, inverse);

    // koc5's home (a delta: at the top, centred, B = C = 0) has its tip at the same X Y Z as its
    // joints, so one map of values after G28 serves the joint-space files and the preview alike.
    std::map<char, double> home;
    for (const auto& j : plain.joints) home[j.output] = j.home;
    REQUIRE(home.size() == 5);
    REQUIRE(home.at('B') == 0);
    REQUIRE(home.at('C') == 0);
    REQUIRE((Kinematics(plain).forward(plain.home_joints()).tip - Eigen::Vector3d(home.at('X'), home.at('Y'), home.at('Z'))).norm() < 1e-12);
    const auto in = moves_of(input, home), p = moves_of(out_plain, home), c = moves_of(out_comp, home), v = moves_of(preview, home);
    REQUIRE(in.size() > 5000);
    REQUIRE(p.size() == in.size());
    REQUIRE(c.size() == in.size());
    REQUIRE(v.size() == in.size());
    const Kinematics k(plain);
    // Printed joints carry 3 decimals, so a difference of two of them is good to 0.001.
    const double printed = 1e-3 + 1e-9;
    double c_min = 1e9, c_max = -1e9, b_min = 1e9, worst_x = 0, worst_z = 0, worst_tip = 0;
    int compared = 0, in_seam = 0, clamped = 0;
    for (std::size_t i = 0; i < in.size(); ++i) {
        CAPTURE(i);
        // E is never touched: the preview carries the input's E, word for word.
        CHECK((std::isnan(in[i].e) ? std::isnan(v[i].e) && std::isnan(c[i].e) : in[i].e == v[i].e && in[i].e == c[i].e));
        const double B = at(p[i], 'B'), C = at(p[i], 'C');
        ++compared;
        c_min = std::min(c_min, C), c_max = std::max(c_max, C), b_min = std::min(b_min, B);
        const double wrapped = C - 360 * std::floor((C + 180) / 360);
        in_seam += std::abs(wrapped) > 135;
        clamped += B < -30;
        // The rotaries and the uncorrected Y are the same; X and Z moved by the table at this B, C.
        CHECK(at(c[i], 'B') == B);
        CHECK(at(c[i], 'C') == C);
        CHECK(std::abs(at(c[i], 'Y') - at(p[i], 'Y')) < 1e-12);
        const double dx = at(p[i], 'X') - at(c[i], 'X') - interpolate(x_by_c, C, true);
        const double dz = at(p[i], 'Z') - at(c[i], 'Z') - interpolate(z_by_b, B, false);
        worst_x = std::max(worst_x, std::abs(dx)), worst_z = std::max(worst_z, std::abs(dz));
        CHECK(std::abs(dx) <= printed);
        CHECK(std::abs(dz) <= printed);
        // The preview through the same compensation is the nominal tool path: FK of the joints
        // the file asked for (here, as written without compensation).
        const Pose want = k.forward({at(p[i], 'X'), at(p[i], 'Y'), at(p[i], 'Z'), B, C});
        const Eigen::Vector3d got(at(v[i], 'X'), at(v[i], 'Y'), at(v[i], 'Z'));
        worst_tip = std::max(worst_tip, (got - want.tip).norm());
        CHECK((got - want.tip).norm() < 2e-3);
        CHECK(std::abs(at(v[i], 'B') - B) < 1e-9);
        CHECK(std::abs(at(v[i], 'C') - C) < 1e-9);
    }
    MESSAGE(compared << " moves: C " << c_min << " .. " << c_max << ", B down to " << b_min << "; " << in_seam << " in the periodic seam, " << clamped
                     << " clamped; X vs table " << worst_x << " mm, Z vs table " << worst_z << " mm, preview tip vs FK " << worst_tip << " mm");
    CHECK(compared > 5000);
    CHECK(c_max - c_min > 720);
    CHECK(in_seam > 100);
    CHECK(clamped > 100);
}
