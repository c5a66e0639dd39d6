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
