// Plate-tilt calibration: synthetic probes with known answers plus noise, and a plate built by
// the machine model itself, recovered through the corrected closed form.
#include <doctest/doctest.h>

#include <Eigen/Geometry>
#include <random>

#include "helpers.hpp"
#include "translators/calibration.hpp"
#include "translators/error.hpp"
#include "translators/kinematics.hpp"
#include "translators/machine.hpp"

using namespace xlate5;
using namespace xlate5::test;

namespace {
Eigen::Matrix3d Rx(double d) { return Eigen::AngleAxisd(rad(d), Eigen::Vector3d::UnitX()).toRotationMatrix(); }
Eigen::Matrix3d Ry(double d) { return Eigen::AngleAxisd(rad(d), Eigen::Vector3d::UnitY()).toRotationMatrix(); }
}  // namespace

TEST_CASE("three exact points give rho and psi exactly; many noisy points within the noise") {
    std::mt19937 rng(8);
    std::uniform_real_distribution<double> U(-1, 1);
    for (int trial = 0; trial < 50; ++trial) {
        const double rho = 3 * U(rng), psi = 3 * U(rng);
        const Eigen::Matrix3d R = Ry(rho) * Rx(psi);  // seed 000 eq. 3.13's order
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

TEST_CASE("rotary zero offset: seed 002 eq. 5.5, and two-sided touches that separate tilt from Z error") {
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
        // Dots at 0, 90, 180, 270 (seed 002's procedure): exact.
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
