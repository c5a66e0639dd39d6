// SPDX-License-Identifier: GPL-3.0-or-later
// Plate-tilt calibration: synthetic probes with known answers plus noise, and a plate built by
// the machine model itself, recovered through the corrected closed form.
#include <doctest/doctest.h>

#include <sys/wait.h>
#include <unistd.h>

#include <Eigen/Geometry>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>

#include "helpers.hpp"
#include "translators/machine/calibration.hpp"
#include "translators/error.hpp"
#include "translators/kinematics/kinematics.hpp"
#include "translators/machine/machine.hpp"

using namespace xlate5;
using namespace xlate5::test;
namespace fs = std::filesystem;

namespace {
Eigen::Matrix3d Rx(double d) { return Eigen::AngleAxisd(rad(d), Eigen::Vector3d::UnitX()).toRotationMatrix(); }
Eigen::Matrix3d Ry(double d) { return Eigen::AngleAxisd(rad(d), Eigen::Vector3d::UnitY()).toRotationMatrix(); }

std::string machine_path(const std::string& name) { return std::string(XLATE5_MACHINE_DIR_FOR_TESTS) + "/" + name + ".toml"; }



// The calibrate commands as a user runs them: the xlate5 binary in a scratch directory of its own.
struct Scratch : TempDir {
    struct Result {
        int code = -1;
        std::string out, err;
    };
    Result run(const std::string& args) const {
        const fs::path out = path / ".out", err = path / ".err";
        const std::string cmd = quote(XLATE5_BINARY) + " " + args + " </dev/null >" + quote(out.string()) + " 2>" + quote(err.string());
        const int status = std::system(cmd.c_str());
        REQUIRE(status != -1);
        REQUIRE(WIFEXITED(status));
        return {WEXITSTATUS(status), read(out), read(err)};
    }
};
}  // namespace

TEST_CASE("three exact points give rho and psi exactly; many noisy points within the noise") {
    std::mt19937 rng(8);
    std::uniform_real_distribution<double> U(-1, 1);
    for (int trial = 0; trial < 50; ++trial) {
        const double rho = 3 * U(rng), psi = 3 * U(rng);
        const Eigen::Matrix3d R = Ry(rho) * Rx(psi);  // Coeytaux et al. (WPI 2017) eq. 3.13's order
        const Eigen::Vector3d origin(10 * U(rng), 10 * U(rng), 5 * U(rng));
        // Three exact probes.
        std::vector<Eigen::Vector3d> three = {origin + R * Eigen::Vector3d(-60, -50, 0), origin + R * Eigen::Vector3d(70, -40, 0),
                                              origin + R * Eigen::Vector3d(0, 65, 0)};
        const PlateFit f = fit_plate(three);
        CHECK(f.rho == doctest::Approx(rho).epsilon(1e-9));
        CHECK(f.psi == doctest::Approx(psi).epsilon(1e-9));
        // The corrected closed form: the normal of R_y(rho) R_x(psi) is (cos psi sin rho, -sin psi, cos psi cos rho).
        const Eigen::Vector3d n(std::cos(rad(psi)) * std::sin(rad(rho)), -std::sin(rad(psi)), std::cos(rad(psi)) * std::cos(rad(rho)));
        CHECK((f.normal - n).norm() < 1e-9);
        // A 5x5 grid over 160 mm with 0.01 mm probe noise: the tilt comes back within
        // atan(noise / half-span) with room for the least-squares average.
        std::vector<Eigen::Vector3d> grid;
        std::normal_distribution<double> noise(0, 0.01);
        for (int i = -2; i <= 2; ++i)
            for (int j = -2; j <= 2; ++j) grid.push_back(origin + R * Eigen::Vector3d(40 * i, 40 * j, 0) + Eigen::Vector3d(0, 0, noise(rng)));
        const PlateFit g = fit_plate(grid);
        const double bound = std::atan(0.01 / 80.0) * 180 / kPi * 3;
        CHECK(std::abs(g.rho - rho) < bound);
        CHECK(std::abs(g.psi - psi) < bound);
        CHECK(g.residual < 0.05);
    }
}

TEST_CASE("a plate built by the wpi5 model is recovered: probing it through the machine's own IK") {
    const double rho = 0.7, psi = -0.45;
    const Machine m = load_machine(std::string(XLATE5_MACHINE_DIR_FOR_TESTS) + "/wpi5.toml", {{"rho", rho}, {"psi", psi}, {"sz", 100}});
    const Kinematics k(m);
    // Touch plate points (x, y, 0) with the nozzle at A = B = 0; the stages then read X Y Z, and
    // the point in the frame is S - (X, Y, Z) (the stages carry the plate, eq. 3.14c).
    std::vector<Eigen::Vector3d> probes;
    for (const Eigen::Vector3d& p : {Eigen::Vector3d(-50, -50, 0), Eigen::Vector3d(50, -40, 0), Eigen::Vector3d(10, 60, 0), Eigen::Vector3d(-30, 30, 0)}) {
        std::vector<double> q(m.joints.size(), 0.0);
        REQUIRE(k.solve_position(p, q).ok());
        probes.push_back(Eigen::Vector3d(0, 0, 100) - Eigen::Vector3d(q[0], q[1], q[2]));
    }
    const PlateFit f = fit_plate(probes);
    CHECK(f.rho == doctest::Approx(rho).epsilon(1e-9));
    CHECK(f.psi == doctest::Approx(psi).epsilon(1e-9));
}

TEST_CASE("set_parameters rewrites only the named [parameters] values and keeps comments") {
    const std::string text = "name = \"t\"\n[parameters]\nrho = 0   # degrees\npsi = 0\nla = 1\n[input]\nrho = 5\n";
    const std::string out = set_parameters(text, "t.toml", {{"rho", 0.5}, {"psi", -0.25}});
    CHECK(contains(out, "rho = 0.500000   # degrees\n"));
    CHECK(contains(out, "psi = -0.250000\n"));
    CHECK(contains(out, "la = 1\n"));
    CHECK(contains(out, "[input]\nrho = 5\n"));  // outside [parameters]: untouched
    CHECK_THROWS_AS(set_parameters(text, "t.toml", {{"nope", 1}}), MachineError);
}

TEST_CASE("rotary zero offset: Grutle (Oslo 2015) eq. 5.5, and two-sided touches that separate tilt from Z error") {
    // A plate tilted by the A offset about x through the origin: Z = Y tan(offset) + z0.
    std::mt19937 rng(21);
    std::uniform_real_distribution<double> U(-1, 1);
    for (int trial = 0; trial < 40; ++trial) {
        const double offset = 2 * U(rng), z0 = 0.3 * U(rng);
        auto touch = [&](double y) { return Eigen::Vector2d(y, y * std::tan(rad(offset)) + z0); };
        // Eq. 5.5 with an exact Z origin: one touch is enough.
        const Eigen::Vector2d one = touch(30) - Eigen::Vector2d(0, z0);
        CHECK(std::atan(one.y() / one.x()) * 180 / kPi == doctest::Approx(offset).epsilon(1e-9));
        // Two sides (Y = +-30) recover both the offset and the Z-origin error.
        const OffsetFit f = fit_rotary_offset({touch(30), touch(-30)});
        CHECK(f.offset_deg == doctest::Approx(offset).epsilon(1e-9));
        CHECK(std::abs(f.z_error - z0) < 1e-9);
        // Noisy touches (0.01 mm) along Y: within the noise.
        std::vector<Eigen::Vector2d> many;
        std::normal_distribution<double> noise(0, 0.01);
        for (double y = -40; y <= 40; y += 10) many.push_back(touch(y) + Eigen::Vector2d(0, noise(rng)));
        const OffsetFit g = fit_rotary_offset(many);
        CHECK(std::abs(g.offset_deg - offset) < std::atan(0.03 / 40) * 180 / kPi);
        CHECK(std::abs(g.z_error - z0) < 0.02);
    }
}

TEST_CASE("rotation centre from dots printed at several angles of C") {
    std::mt19937 rng(4);
    std::uniform_real_distribution<double> U(-1, 1);
    for (int trial = 0; trial < 40; ++trial) {
        const Eigen::Vector2d centre(3 * U(rng), 3 * U(rng));
        const double r = 5 + 20 * (U(rng) + 1);
        // Dots at 0, 90, 180, 270 (the procedure of Grutle, Oslo 2015): exact.
        std::vector<Eigen::Vector2d> dots;
        for (int k = 0; k < 4; ++k) dots.push_back(centre + r * Eigen::Vector2d(std::cos(rad(90.0 * k + 10 * trial)), std::sin(rad(90.0 * k + 10 * trial))));
        const CircleFit f = fit_circle(dots);
        CHECK((f.centre - centre).norm() < 1e-9);
        CHECK(f.radius == doctest::Approx(r).epsilon(1e-9));
        // Eight noisy dots over only 120 degrees: still within a few times the noise.
        std::vector<Eigen::Vector2d> arc;
        std::normal_distribution<double> noise(0, 0.02);
        for (int k = 0; k < 8; ++k)
            arc.push_back(centre + r * Eigen::Vector2d(std::cos(rad(15.0 * k)), std::sin(rad(15.0 * k))) + Eigen::Vector2d(noise(rng), noise(rng)));
        const CircleFit g = fit_circle(arc);
        CHECK((g.centre - centre).norm() < 0.3);
        CHECK(g.residual < 0.1);
    }
}

TEST_CASE("pivot and link lengths from measured tips: rw2's la, lb and wpi5's z_offset") {
    const std::string dir = XLATE5_MACHINE_DIR_FOR_TESTS;
    auto read = [](const std::string& path) {
        std::FILE* f = std::fopen(path.c_str(), "rb");
        REQUIRE(f);
        std::string t;
        char buf[4096];
        std::size_t n;
        while ((n = std::fread(buf, 1, sizeof buf, f)) > 0) t.append(buf, n);
        std::fclose(f);
        return t;
    };
    std::mt19937 rng(13);
    std::uniform_real_distribution<double> U(-1, 1);
    std::normal_distribution<double> noise(0, 0.02);
    // rw2: the truth is la = 29 (table 4.1), lb = 47.9; the fit starts from the script's 26.5 / 45.
    {
        const std::string text = read(dir + "/rw2.toml");
        const Machine truth = load_machine_text(text, "rw2", {{"la", 29.0}, {"lb", 47.9}});
        const Kinematics k(truth);
        std::vector<std::vector<double>> joints;
        std::vector<Eigen::Vector3d> tips;
        for (int i = 0; i < 12; ++i) {
            std::vector<double> q = {100 + 20 * U(rng), 100 + 20 * U(rng), 20 + 5 * U(rng), 150 * U(rng), 60 * U(rng)};
            joints.push_back(q);
            tips.push_back(k.forward(q).tip + Eigen::Vector3d(noise(rng), noise(rng), noise(rng)));
        }
        const ParameterFit f = fit_parameters(text, "rw2", {"la", "lb"}, {{"la", 26.5}, {"lb", 45.0}}, joints, tips);
        MESSAGE("rw2: la " << f.values.at("la") << ", lb " << f.values.at("lb") << ", residual " << f.residual << " mm");
        CHECK(std::abs(f.values.at("la") - 29.0) < 0.05);
        CHECK(std::abs(f.values.at("lb") - 47.9) < 0.05);
        CHECK(f.residual < 0.1);
    }
    // wpi5: the A pivot height, exact data.
    {
        const std::string text = read(dir + "/wpi5.toml");
        const Machine truth = load_machine_text(text, "wpi5", {{"z_offset", 37.5}});
        const Kinematics k(truth);
        std::vector<std::vector<double>> joints;
        std::vector<Eigen::Vector3d> tips;
        for (int i = 0; i < 6; ++i) {
            std::vector<double> q = {30 * U(rng), 30 * U(rng), -50 + 10 * U(rng), 60 * U(rng), 180 * U(rng)};
            joints.push_back(q);
            tips.push_back(k.forward(q).tip);
        }
        const ParameterFit f = fit_parameters(text, "wpi5", {"z_offset"}, {{"z_offset", 40.0}}, joints, tips);
        CHECK(f.values.at("z_offset") == doctest::Approx(37.5).epsilon(1e-8));
        CHECK(f.residual < 1e-8);
    }
}

TEST_CASE("CLI: calibrate offset writes pentarod's a_offset from touches the tilted table gives, within the noise") {
    const Scratch d;
    // The truth: a table tilted 0.8 degrees at A = 0. Touches are simulated with pentarod's own
    // FK: at (X 0, Y y, A 0, C 0), the Z where the nozzle tip meets the plate (part z = 0),
    // then 0.01 mm of probe noise.
    const double truth = 0.8, sigma = 0.01;
    const Machine m = load_machine(machine_path("pentarod"), {{"a_offset", truth}});
    const Kinematics k(m);
    std::mt19937 rng(5);
    std::normal_distribution<double> noise(0, sigma);
    std::string csv = "# y, z\n";
    double sum_y2 = 0;
    for (double y = -40; y <= 40; y += 10) {
        // The tip's part-frame z is affine in the Z joint: two evaluations give the touch.
        const double z0 = k.forward({0, y, 0, 0, 0}).tip.z(), z1 = k.forward({0, y, 1, 0, 0}).tip.z();
        char line[64];
        std::snprintf(line, sizeof line, "%g, %.6f\n", y, -z0 / (z1 - z0) + noise(rng));
        csv += line;
        sum_y2 += y * y;
    }
    const fs::path touches = d.write("touches.csv", csv);
    // A copy of the machine file, so the refusal below can be checked on a file we own.
    const fs::path original = d.write("pentarod.toml", read(machine_path("pentarod")));
    const fs::path out = d.path / "pentarod-cal.toml";
    const Scratch::Result r = d.run("--machine " + quote(original.string()) + " calibrate offset " + quote(touches.string()) + " --param a_offset -o " +
                                quote(out.string()));
    CAPTURE(r.out);
    CAPTURE(r.err);
    REQUIRE(r.code == 0);
    CHECK(contains(r.out, "a_offset: 0.000000 -> "));
    CHECK(contains(r.out, "largest residual"));
    // The written file loads and holds the tilt within 4 standard deviations of a line fit's slope.
    const Machine cal = load_machine(out.string());
    const double bound = 4 * sigma / std::sqrt(sum_y2) * 180 / kPi;
    MESSAGE("a_offset recovered " << cal.parameters.at("a_offset") << " (truth " << truth << ", bound " << bound << ")");
    CHECK(std::abs(cal.parameters.at("a_offset") - truth) < bound);
    // Never over the original, whichever way its path is spelled; the original is unchanged.
    const std::string before = read(original);
    for (const fs::path& target : {original, d.path / "." / "pentarod.toml"}) {
        const Scratch::Result again = d.run("--machine " + quote(original.string()) + " calibrate offset " + quote(touches.string()) +
                                        " --param a_offset -o " + quote(target.string()));
        CHECK(again.code == 2);
        CHECK(contains(again.err, "is the machine file itself"));
    }
    CHECK(read(original) == before);
    // -o without --param, and a parameter the machine does not have.
    CHECK(d.run("--machine pentarod calibrate offset " + quote(touches.string()) + " -o " + quote((d.path / "x.toml").string())).code == 2);
    const Scratch::Result nope = d.run("--machine pentarod calibrate offset " + quote(touches.string()) + " --param b_offset -o " +
                                   quote((d.path / "x.toml").string()));
    CHECK(nope.code == 3);
    CHECK(contains(nope.err, "no 'b_offset'"));
    CHECK_FALSE(fs::exists(d.path / "x.toml"));
    // --set applies here as everywhere: the old value shown is the one set; an unknown name is refused.
    CHECK(contains(d.run("--machine pentarod --set a_offset=0.3 calibrate offset " + quote(touches.string()) + " --param a_offset").out,
                   "a_offset: 0.300000 -> "));
    CHECK(d.run("--machine pentarod --set nope=1 calibrate offset " + quote(touches.string()) + " --param a_offset").code == 3);
}

TEST_CASE("CLI: calibrate centre writes the C axis position (pentarod cx, cy; koc5 wx, wy) from dots, within the noise") {
    const Scratch d;
    const double sigma = 0.01;
    std::mt19937 rng(17);
    std::normal_distribution<double> noise(0, sigma);
    struct Case {
        const char* machine;
        const char* names;
        std::map<std::string, double> truth;
        std::vector<double> joints;  // the nozzle's place; C (last) is turned for each dot
    };
    const Case cases[] = {{"pentarod", "cx,cy", {{"cx", 1.3}, {"cy", -0.7}}, {15, 5, 0, 0, 0}},
                          {"koc5", "wx,wy", {{"wx", -2.1}, {"wy", 0.9}}, {10, -5, 0, 0, 0}}};
    for (const Case& c : cases) {
        CAPTURE(c.machine);
        // Dots printed with the nozzle held still while the plate turns by C (Grutle, Oslo 2015: every
        // 90 degrees; here every 45), found through the machine's own FK: the plate point under
        // the nozzle. Read back at C = 0 the part frame is the machine frame.
        const Machine truth = load_machine(machine_path(c.machine), c.truth);
        const Kinematics k(truth);
        std::string csv;
        for (int i = 0; i < 8; ++i) {
            std::vector<double> q = c.joints;
            q.back() = 45.0 * i;
            const Eigen::Vector3d dot = k.forward(q).tip;
            char line[80];
            std::snprintf(line, sizeof line, "%.6f,%.6f\n", dot.x() + noise(rng), dot.y() + noise(rng));
            csv += line;
        }
        const fs::path dots = d.write(std::string(c.machine) + "-dots.csv", csv);
        const fs::path out = d.path / (std::string(c.machine) + "-cal.toml");
        const Scratch::Result r = d.run(std::string("--machine ") + c.machine + " calibrate centre " + quote(dots.string()) + " --param " + c.names +
                                    " -o " + quote(out.string()));
        CAPTURE(r.out);
        CAPTURE(r.err);
        REQUIRE(r.code == 0);
        const Machine cal = load_machine(out.string());
        // Eight dots with independent x, y noise: the centre's error is about sigma / 2 per axis.
        for (const auto& [name, value] : c.truth) {
            CHECK(contains(r.out, name + ": 0.000000 -> "));
            CHECK(std::abs(cal.parameters.at(name) - value) < 4 * sigma);
        }
        // Everything else in the file is as it was.
        for (const auto& [name, value] : load_machine(machine_path(c.machine)).parameters)
            if (!c.truth.count(name)) CHECK(cal.parameters.at(name) == value);
        CHECK(d.run(std::string("--machine ") + c.machine + " calibrate centre " + quote(dots.string()) + " --param " + c.names + " -o " +
                         quote(machine_path(c.machine)))
                  .code == 2);
    }
    // Two names, X then Y.
    const fs::path dots = d.path / "pentarod-dots.csv";
    CHECK(d.run("--machine pentarod calibrate centre " + quote(dots.string()) + " --param cx -o " + quote((d.path / "y.toml").string())).code == 2);
    CHECK_FALSE(fs::exists(d.path / "y.toml"));
}

TEST_CASE("conditioning: the condition numbers of the fits against their closed forms; near-degenerate data that is fine still fits exactly") {
    // Plate: the corners of an a x b rectangle, centred, have singular values a and b (each
    // direction's sum of squares is 4 (a/2)^2 = a^2): the condition number is a / b.
    for (const double b : {4.0, 20.0, 200.0}) {
        CAPTURE(b);
        const double a = 200, rho = 0.6, psi = -0.35;
        const Eigen::Matrix3d R = Ry(rho) * Rx(psi);
        std::vector<Eigen::Vector3d> corners;
        for (const double x : {-a / 2, a / 2})
            for (const double y : {-b / 2, b / 2}) corners.push_back(Eigen::Vector3d(5, -3, 1) + R * Eigen::Vector3d(x, y, 0));
        const PlateFit f = fit_plate(corners);
        CHECK(f.condition == doctest::Approx(a / b).epsilon(1e-9));
        CHECK(f.rho == doctest::Approx(rho).epsilon(1e-9));  // a 200 x 4 mm strip (50): still exact
        CHECK(f.psi == doctest::Approx(psi).epsilon(1e-9));
    }
    {
        std::vector<Eigen::Vector3d> strip = {{-100, -0.5, 0}, {100, -0.5, 0}, {-100, 0.5, 0.001}, {100, 0.5, 0.001}};  // 200: past the bound
        CHECK_THROWS_AS(fit_plate(strip), CalibrationError);
    }
    // Offset: two touches give the 2 x 2 design (y, 1); its columns scaled to unit length meet
    // at an angle with cosine c = (y1 + y2) / sqrt(2 (y1^2 + y2^2)), and the singular values of two
    // unit columns are sqrt(1 +- c): the condition number is sqrt((1 + c) / (1 - c)).
    for (const auto& [y1, y2] : std::vector<std::pair<double, double>>{{30, -30}, {10, 40}, {60, 90}, {30, 30.5}}) {
        CAPTURE_BINDING(y1);
        CAPTURE_BINDING(y2);
        const double c = (y1 + y2) / std::sqrt(2 * (y1 * y1 + y2 * y2));
        const double expected = std::sqrt((1 + c) / (1 - c));
        const double offset = 0.7, z0 = 0.12;
        auto touch = [&](double y) { return Eigen::Vector2d(y, y * std::tan(rad(offset)) + z0); };
        if (expected > kMaxCondition) {
            CHECK_THROWS_AS(fit_rotary_offset({touch(y1), touch(y2)}), CalibrationError);
            continue;
        }
        const OffsetFit f = fit_rotary_offset({touch(y1), touch(y2)});
        CHECK(f.condition == doctest::Approx(expected).epsilon(1e-9));
        CHECK(f.offset_deg == doctest::Approx(offset).epsilon(1e-9));  // touches on one side only (10, 40): exact still
        CHECK(std::abs(f.z_error - z0) < 1e-9);
    }
    // Circle: four dots 90 degrees apart have orthogonal columns (x, y, 1) about their centroid,
    // of lengths sqrt(2), sqrt(2) and 2 in units of their RMS spread: the condition number is sqrt(2).
    const CircleFit square = fit_circle({{12, 3}, {2, 13}, {-8, 3}, {2, -7}});
    CHECK(square.condition == doctest::Approx(std::sqrt(2.0)).epsilon(1e-9));
    // Dots over a quarter turn only: ill-conditioned but within the bound, and exact.
    std::vector<Eigen::Vector2d> quarter, sliver;
    for (int k = 0; k < 5; ++k) quarter.push_back(Eigen::Vector2d(1.5, -2) + 25 * Eigen::Vector2d(std::cos(rad(22.5 * k)), std::sin(rad(22.5 * k))));
    const CircleFit q = fit_circle(quarter);
    MESSAGE("dots over 90 degrees: condition number " << q.condition);
    CHECK(q.condition > square.condition);
    CHECK((q.centre - Eigen::Vector2d(1.5, -2)).norm() < 1e-9);
    CHECK(q.radius == doctest::Approx(25).epsilon(1e-9));
    // Over one degree the dots are a line to within 0.001 of their spread: refused.
    for (int k = 0; k < 5; ++k) sliver.push_back(25 * Eigen::Vector2d(std::cos(rad(0.25 * k)), std::sin(rad(0.25 * k))));
    CHECK_THROWS_AS(fit_circle(sliver), CalibrationError);
    // Fourier: angles evenly over the turn make the basis's columns orthogonal, 1 of length
    // sqrt(n) and each cosine and sine of length sqrt(n / 2): the condition number is sqrt(2).
    std::vector<double> angle, error;
    for (int a = 0; a < 360; a += 30) angle.push_back(a), error.push_back(0.2 + 0.1 * std::cos(rad(a)) - 0.3 * std::sin(rad(2.0 * a)));
    double residual = 0, condition = 0;
    const CompensationTerm t = fit_fourier(angle, error, 2, residual, &condition);
    CHECK(condition == doctest::Approx(std::sqrt(2.0)).epsilon(1e-9));
    CHECK(t.a0 == doctest::Approx(0.2).epsilon(1e-9));
    CHECK(t.sines[1] == doctest::Approx(-0.3).epsilon(1e-9));
    // Two harmonics from angles over a quarter turn: the basis is near-degenerate: refused.
    std::vector<double> narrow, narrow_error;
    for (int a = 0; a <= 90; a += 15) narrow.push_back(a), narrow_error.push_back(0.1 * std::cos(rad(a)));
    CHECK_THROWS_AS(fit_fourier(narrow, narrow_error, 2, residual), CalibrationError);
    CHECK_NOTHROW(fit_fourier(narrow, narrow_error, 1, residual));  // one harmonic over 90 degrees is within the bound
}

TEST_CASE("CLI: degenerate measurements are refused with the reason and what to measure; nothing non-finite is printed or written") {
    const Scratch d;
    const fs::path copy = d.path / "calibrated.toml";
    struct Case {
        const char* what;
        std::string args;
        const char* reason;
        const char* instead;
    };
    // rw2's tips at B = 0 do not depend on lb (eq. 4.5: every lb term has sin B or 1 - cos B).
    std::string b_zero;
    for (const double a : {0.0, 45.0, 90.0, -60.0}) {
        char line[128];
        std::snprintf(line, sizeof line, "100,100,20,%g,0,%.6f,%.6f,20\n", a, 100 - std::sin(rad(a)) * 26.5, 100 + 26.5 - std::cos(rad(a)) * 26.5);
        b_zero += line;
    }
    const Case cases[] = {
        // The issue's: three plate probes along one edge (the fit said rho = 180, psi = -90, residual 0).
        {"plate along an edge", "--machine wpi5 calibrate plate " + quote(d.write("edge.csv", "0,0,0.10\n100,0,0.15\n200,0,0.20\n").string()) + " -o " +
                                    quote(copy.string()),
         "lie on a line", "near three corners of the plate"},
        {"four identical dots", "calibrate centre " + quote(d.write("same.csv", "5,5\n5,5\n5,5\n5,5\n").string()) + " --machine pentarod --param cx,cy -o " +
                                    quote(copy.string()),
         "all in one place", "0, 90, 180 and 270 degrees"},
        {"dots on a line", "calibrate centre " + quote(d.write("line.csv", "0,0\n10,10\n20,20\n30,30\n").string()), "lie on a line", "angles spread around the turn"},
        {"two touches at one Y", "--machine pentarod calibrate offset " + quote(d.write("oneY.csv", "30,0.10\n30,0.40\n").string()) + " --param a_offset -o " +
                                     quote(copy.string()),
         "Y positions are the same or nearly", "both sides of the axis"},
        {"angles that alias", "calibrate fit " + quote(d.write("alias.csv", "0,1\n180,2\n360,3\n").string()), "cannot separate 1 harmonic",
         "fit fewer harmonics"},
        {"a parameter the tips do not depend on", "--machine rw2 calibrate pivots " + quote(d.write("bzero.csv", b_zero).string()) + " --fit la,lb -o " +
                                                      quote(copy.string()),
         "do not depend on 'lb'", "joint values that move it"},
        // Tips hundreds of kilometres from any the head can reach: b1037f8 printed la = 295400640.9 with exit 0.
        {"tips no parameter values fit", "--machine rw2 calibrate pivots " +
                                             quote(d.write("far.csv", "100,100,20,0,0,5e8,1,1\n100,100,20,90,30,-5e8,1,3\n100,100,20,45,60,1,1e8,2\n").string()) +
                                             " --fit la,lb -o " + quote(copy.string()),
         "the fit does not settle", "start from values near the machine's"},
        {"a number past 1e9", "calibrate plate " + quote(d.write("huge.csv", "0,0,0\n1e300,0,0\n0,100,0\n").string()), "huge.csv:2:1: a number beyond +-1e9", ""},
    };
    for (const Case& c : cases) {
        CAPTURE(c.what);
        const Scratch::Result r = d.run(c.args);
        CAPTURE(r.out);
        CAPTURE(r.err);
        CHECK(r.code == 1);
        CHECK(contains(r.err, c.reason));
        CHECK(contains(r.err, c.instead));
        CHECK_FALSE(fs::exists(copy));
        for (const char* bad : {"nan", "inf", "e+"}) CHECK_FALSE(contains(r.out, bad));
    }
    // The same commands on measurements that determine the values: accepted, the condition number shown.
    const Scratch::Result plate = d.run("--machine wpi5 calibrate plate " + quote(d.write("plate.csv", "0,0,0.10\n200,0,0.15\n0,150,0.12\n").string()));
    CHECK(plate.code == 0);
    CHECK(contains(plate.out, "(condition number "));
}

TEST_CASE("CLI: a measurement table with a spreadsheet's header row reads as the same table without it") {
    // Every spreadsheet writes its column names first; b1037f8 refused them as "'a' is not a number".
    const Scratch d;
    std::string rows;
    for (int a = 0; a < 360; a += 30) {
        char line[64];
        std::snprintf(line, sizeof line, "%d,%.4f\n", a, 0.05 * std::cos(rad(a)) + 0.02 * std::sin(rad(2.0 * a)));
        rows += line;
    }
    const auto plain = d.run("calibrate fit " + quote(d.write("plain.csv", rows).string()) + " --order 2");
    REQUIRE(plain.code == 0);
    for (const std::string header : {"angle,error\n", "\"angle (deg)\", \"error (mm)\"\r\n", "# measured 2026-11-28\nA,err_mm\n"}) {
        CAPTURE(header);
        const auto with = d.run("calibrate fit " + quote(d.write("header.csv", header + rows).string()) + " --order 2");
        CHECK(with.code == 0);
        // The same fit: the numbers after the first line (which names the file) agree.
        CHECK(with.out.substr(with.out.find('\n')) == plain.out.substr(plain.out.find('\n')));
    }
    // Names after the first measurement, a row of another width, or "nan" are still refused.
    for (const std::string bad : {"0,0.01\nangle,error\n30,0.02\n", "angle,error,extra\n0,0.01\n", "nan,inf\n0,0.01\n"}) {
        CAPTURE(bad);
        CHECK(d.run("calibrate fit " + quote(d.write("bad.csv", bad).string())).code == 1);
    }
}
