// SPDX-License-Identifier: GPL-3.0-or-later
// Kinematics against the sources' own formulas (written out here independently of the machine
// files), and FK/IK round trips on random poses for every shipped machine.
#include <doctest/doctest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <map>
#include <memory>
#include <random>

#include "helpers.hpp"
#include "translators/error.hpp"
#include "translators/pipeline/joint_limits.hpp"
#include "translators/kinematics/kinematics.hpp"
#include "translators/machine/machine.hpp"

using namespace xlate5;
using xlate5::test::sampled;

namespace {

constexpr double kPi = 3.14159265358979323846;
double rad(double deg) { return deg * kPi / 180.0; }

Machine machine(const std::string& name, const std::map<std::string, double>& overrides = {}) {
    return load_machine(std::string(XLATE5_MACHINE_DIR_FOR_TESTS) + "/" + name + ".toml", overrides);
}

int joint(const Machine& m, char name) {
    const int j = m.joint_index(name);
    REQUIRE(j >= 0);
    return j;
}

Eigen::Matrix3d Rx(double deg) { return Eigen::AngleAxisd(rad(deg), Eigen::Vector3d::UnitX()).toRotationMatrix(); }
Eigen::Matrix3d Ry(double deg) { return Eigen::AngleAxisd(rad(deg), Eigen::Vector3d::UnitY()).toRotationMatrix(); }
Eigen::Matrix3d Rz(double deg) { return Eigen::AngleAxisd(rad(deg), Eigen::Vector3d::UnitZ()).toRotationMatrix(); }

// Angle difference modulo 360.
double angle_diff(double a, double b) { return std::abs(wrap180(a - b)); }

// Joint values drawn uniformly inside each joint's limits (an unbounded rotary: two turns either way).
std::vector<double> random_joints(const Machine& m, std::mt19937& rng) {
    std::uniform_real_distribution<double> U(0, 1);
    std::vector<double> q(m.joints.size());
    for (std::size_t j = 0; j < q.size(); ++j) {
        const Joint& J = m.joints[j];
        const double lo = J.bounded() ? J.min : -720, hi = J.bounded() ? J.max : 720;
        q[j] = lo + (hi - lo) * U(rng);
    }
    return q;
}

// Every axis of the machine's chains, its fixed rotations, its rotary axes' points and its tool
// axis turned or moved at random: a layout unlike any shipped one, for tests that must hold for
// any machine.
void turn_at_random(Machine& m, std::mt19937& rng) {
    std::uniform_real_distribution<double> U(0, 1);
    auto unit = [&] { return Eigen::Vector3d(U(rng) - 0.5, U(rng) - 0.5, U(rng) - 0.5).normalized(); };
    for (auto* chain : {&m.part_chain, &m.tool_chain})
        for (auto& e : *chain) {
            if (e.kind == ChainElement::Kind::Fixed) e.fixed.linear() = Eigen::AngleAxisd(U(rng) * 6, unit()).toRotationMatrix();
            else e.axis = unit();
            if (e.kind == ChainElement::Kind::Rotary) e.point = 50 * unit();
        }
    m.tool_axis = unit();
}

// pentarod's shape (two turns about coordinate axes through the origin, three linear links in
// the tool chain: the kinematics' closed form) with turns about axes k1 != k2 (each +-1 times
// it), t picking the signs and whether the tool's axis and linear directions are drawn at random.
Machine two_turns(Machine m, int k1, int k2, int t, std::mt19937& rng) {
    std::uniform_real_distribution<double> U(0, 1);
    Eigen::Vector3d a1 = Eigen::Vector3d::Zero(), a2 = Eigen::Vector3d::Zero();
    a1[k1] = t & 1 ? -1 : 1;
    a2[k2] = t & 2 ? -1 : 1;
    int turns = 0;
    for (auto& e : m.part_chain)
        if (e.kind == ChainElement::Kind::Rotary) e.axis = turns++ == 0 ? a1 : a2;
    if (t & 4)
        for (auto& e : m.tool_chain) e.axis = Eigen::Vector3d(U(rng) - 0.5, U(rng) - 0.5, U(rng) - 0.5);
    if (t & 8) m.tool_axis = Eigen::Vector3d(U(rng) - 0.5, U(rng) - 0.5, U(rng) - 0.5).normalized();
    return m;
}

}  // namespace

TEST_CASE("wrap180 gives (-180, 180], as the remainder of a division by 360 defines it") {
    // The definition, written out: fmod's exact remainder, then one turn added or taken.
    auto reference = [](double d) {
        double r = std::fmod(d, 360.0);
        if (r <= -180.0) r += 360.0;
        if (r > 180.0) r -= 360.0;
        return r;
    };
    std::mt19937_64 rng(9);
    std::uniform_real_distribution<double> U(-1, 1);
    std::vector<double> values = {0.0, -0.0, 180.0, -180.0, 360.0, -360.0, 359.99999999999994, -359.99999999999994, 540.0, 1e9, -1e9};
    for (int i = 0; i < 200000; ++i) values.push_back(U(rng) * std::pow(10.0, 4 * std::abs(U(rng))));
    // Past the library call's shortcut (2^40) and on both sides of multiples of 180 and 360, where
    // a quotient one off shows.
    for (int i = 0; i < 100000; ++i) {
        const double d = U(rng) * std::pow(10.0, 15 * std::abs(U(rng)));
        for (const double m : {360.0 * std::round(d / 360), 180.0 * std::round(d / 180)})
            values.insert(values.end(), {d, m, std::nextafter(m, 1e300), std::nextafter(m, -1e300)});
    }
    for (const double d : values) {
        const double mine = wrap180(d), ref = reference(d);
        CHECK(std::memcmp(&mine, &ref, sizeof mine) == 0);
    }
}

TEST_CASE("rw2 equals Andersons (Twente 2023) eq. 4.5 over a grid of poses") {
    const Machine m = machine("rw2");
    const Kinematics k(m);
    const double la = 26.5, lb = 47.9;  // appendix C.2
    const int A = joint(m, 'A'), B = joint(m, 'B');
    int checked = 0;
    for (double a = -165; a <= 165; a += 15) {
        for (double b = -90; b <= 90; b += 15) {
            for (const Eigen::Vector3d& tip : {Eigen::Vector3d(100, 100, 10), Eigen::Vector3d(12.5, -3, 0.28), Eigen::Vector3d(200, 150, 120)}) {
                std::vector<double> q(m.joints.size(), 0.0);
                q[A] = a;
                q[B] = b;
                REQUIRE(k.solve_position(tip, q).ok());
                // Eq. 4.5 as printed.
                const double X = tip.x() + std::sin(rad(a)) * la + std::cos(rad(a)) * std::sin(rad(b)) * lb;
                const double Y = tip.y() - la + std::cos(rad(a)) * la - std::sin(rad(a)) * std::sin(rad(b)) * lb;
                const double Z = tip.z() + std::cos(rad(b)) * lb - lb;
                CHECK(q[joint(m, 'X')] == doctest::Approx(X).epsilon(1e-12));
                CHECK(q[joint(m, 'Y')] == doctest::Approx(Y).epsilon(1e-12));
                CHECK(q[joint(m, 'Z')] == doctest::Approx(Z).epsilon(1e-12));
                CHECK(q[A] == a);
                CHECK(q[B] == b);
                ++checked;
            }
        }
    }
    CHECK(checked == 23 * 13 * 3);
}

TEST_CASE("rw2 with la = 29 reproduces Andersons (Twente 2023) table 4.1's theoretical X and Y within 0.01 mm") {
    const Machine m = machine("rw2", {{"la", 29.0}});
    const Kinematics k(m);
    struct Row { double a, x, y; };
    // Table 4.1, "Theoretical" columns (tip at X' = Y' = 100, B = 0).
    const Row rows[] = {{-135, 79.49, 50.49}, {-90, 71.00, 71.00}, {-45, 79.49, 91.51}, {0, 100.00, 100.00},
                        {45, 120.51, 91.51}, {90, 129.00, 71.00}, {135, 120.51, 50.49}};
    for (const Row& r : rows) {
        std::vector<double> q(m.joints.size(), 0.0);
        q[joint(m, 'A')] = r.a;
        REQUIRE(k.solve_position({100, 100, 0}, q).ok());
        CAPTURE(r.a);
        CHECK(std::abs(q[joint(m, 'X')] - r.x) <= 0.01);
        CHECK(std::abs(q[joint(m, 'Y')] - r.y) <= 0.01);
    }
    // And la = 26.5 (the script's value) does not reproduce it: the parameter matters.
    const Machine m2 = machine("rw2");
    const Kinematics k2(m2);
    std::vector<double> q(m2.joints.size(), 0.0);
    q[joint(m2, 'A')] = 90;
    REQUIRE(k2.solve_position({100, 100, 0}, q).ok());
    CHECK(std::abs(q[joint(m2, 'X')] - 129.00) > 1.0);
}

TEST_CASE("wpi5 equals Coeytaux et al. (WPI 2017) eq. 3.14c for random plate tilts and pivot offsets") {
    std::mt19937 rng(14);
    std::uniform_real_distribution<double> U(-1, 1);
    int checked = 0;
    for (int trial = 0; trial < 40; ++trial) {
        const double rho = 3 * U(rng), psi = 3 * U(rng), zoff = 40 + 30 * U(rng);
        const Eigen::Vector3d S(20 * U(rng), 20 * U(rng), 50 + 20 * U(rng));
        const Machine m = machine("wpi5", {{"rho", rho}, {"psi", psi}, {"z_offset", zoff}, {"sx", S.x()}, {"sy", S.y()}, {"sz", S.z()}});
        const Kinematics k(m);
        for (int i = 0; i < 25; ++i) {
            const double th = 85 * U(rng), ph = 180 * U(rng);
            const Eigen::Vector3d p(40 * U(rng), 40 * U(rng), 20 + 20 * U(rng));
            std::vector<double> q(m.joints.size(), 0.0);
            q[joint(m, 'A')] = th;
            q[joint(m, 'B')] = ph;
            REQUIRE(k.solve_position(p, q).ok());
            // Eq. 3.14c: P_frame = S - z_offset (-sin th, 0, 1 - cos th) - R_y(th) R_z(ph) R_y(rho) R_x(psi) p
            const Eigen::Vector3d expect = S - zoff * Eigen::Vector3d(-std::sin(rad(th)), 0, 1 - std::cos(rad(th))) -
                                           Ry(th) * Rz(ph) * Ry(rho) * Rx(psi) * p;
            CHECK(q[joint(m, 'X')] == doctest::Approx(expect.x()).epsilon(1e-12));
            CHECK(q[joint(m, 'Y')] == doctest::Approx(expect.y()).epsilon(1e-12));
            CHECK(q[joint(m, 'Z')] == doctest::Approx(expect.z()).epsilon(1e-12));
            // The nozzle points along the frame's +z: R_p u = z.
            const Eigen::Vector3d u = k.forward(q).axis;
            CHECK(((Ry(th) * Rz(ph) * Ry(rho) * Rx(psi) * u) - Eigen::Vector3d::UnitZ()).norm() < 1e-12);
            ++checked;
        }
    }
    CHECK(checked == 1000);
}

TEST_CASE("pentarod equals Grutle (Oslo 2015) pseudo code 4.1 and its tool vector") {
    const Machine m = machine("pentarod");
    const Kinematics k(m);
    // Worked values of lines 10-12 (x, y, z, A, C) -> (X', Y', Z').
    struct Row { double x, y, z, a, c, X, Y, Z; };
    const Row rows[] = {{1.3, -2.1, 0.7, 30, 40, 2.345712, -1.019498, 0.219683}, {0, 10, 0, 45, 0, 0, 7.071068, 7.071068},
                        {0, 0, 5, 90, 90, 0, -5, 0}, {5, 5, 2, 60, -135, 0, -5.267585, -5.123724}};
    for (const Row& r : rows) {
        std::vector<double> q(m.joints.size(), 0.0);
        q[joint(m, 'A')] = r.a;
        q[joint(m, 'C')] = r.c;
        REQUIRE(k.solve_position({r.x, r.y, r.z}, q).ok());
        CHECK(q[joint(m, 'X')] == doctest::Approx(r.X).epsilon(1e-6));
        CHECK(q[joint(m, 'Y')] == doctest::Approx(r.Y).epsilon(1e-6));
        CHECK(q[joint(m, 'Z')] == doctest::Approx(r.Z).epsilon(1e-6));
    }
    std::mt19937 rng(2);
    std::uniform_real_distribution<double> U(-1, 1);
    for (int i = 0; i < 500; ++i) {
        const double a = 89 * U(rng), c = 179 * U(rng);
        const Eigen::Vector3d p(50 * U(rng), 50 * U(rng), 30 * U(rng) + 30);
        // Lines 10-12 written out as printed.
        const double ca = std::cos(rad(a)), sa = std::sin(rad(a)), cc = std::cos(rad(c)), sc = std::sin(rad(c));
        const Eigen::Vector3d expect(p.x() * cc - p.y() * sc, p.x() * ca * sc + p.y() * ca * cc - p.z() * sa,
                                     p.x() * sa * sc + p.y() * sa * cc + p.z() * ca);
        // Tool vector of Grutle 2015's pseudo code 4.1: u = (sin A sin C, sin A cos C, cos A); IK must recover a pose
        // with that axis and those machine coordinates.
        const Eigen::Vector3d u(sa * sc, sa * cc, ca);
        std::vector<double> prev(m.joints.size(), 0.0);
        prev[joint(m, 'A')] = a + 1;  // near the true solution, so IK picks it over (-A, C + 180)
        prev[joint(m, 'C')] = c - 2;
        std::vector<double> q;
        REQUIRE(k.inverse({p, u}, prev, q).ok());
        CHECK(q[joint(m, 'A')] == doctest::Approx(a).epsilon(1e-9));
        CHECK(angle_diff(q[joint(m, 'C')], c) < 1e-9);
        CHECK((Eigen::Vector3d(q[joint(m, 'X')], q[joint(m, 'Y')], q[joint(m, 'Z')]) - expect).norm() < 1e-9);
    }
}

TEST_CASE("koc5's build direction is Isa (Koç 2018) eq. 11, and IK returns (C, B) or (C + 180, -B)") {
    const Machine m = machine("koc5");
    const Kinematics k(m);
    std::mt19937 rng(4);
    std::uniform_real_distribution<double> U(-1, 1);
    for (int i = 0; i < 1000; ++i) {
        const double th = 179 * U(rng), ph = 85 * U(rng);
        std::vector<double> q(m.joints.size(), 0.0);
        q[joint(m, 'C')] = th;
        q[joint(m, 'B')] = ph;
        // Eq. 11: n_b = (-cos th sin ph, -sin th sin ph, cos ph)
        const Eigen::Vector3d nb(-std::cos(rad(th)) * std::sin(rad(ph)), -std::sin(rad(th)) * std::sin(rad(ph)), std::cos(rad(ph)));
        CHECK((k.forward(q).axis - nb).norm() < 1e-12);
        const auto sols = k.orientation_solutions(nb);
        REQUIRE(sols.size() == 2);
        // rotary_joints() order is the orientation product's; map back to B and C.
        bool found = false, found_flip = false;
        for (int si = 0; si < sols.count; ++si) {
            double b = 0, c = 0;
            for (std::size_t r = 0; r < 2; ++r)
                (k.rotary_joints()[r] == joint(m, 'B') ? b : c) = sols.angle[si][r];
            found = found || (std::abs(b - ph) < 1e-9 && angle_diff(c, th) < 1e-9);
            found_flip = found_flip || (std::abs(b + ph) < 1e-9 && angle_diff(c, th + 180) < 1e-9);
        }
        CHECK(found);
        CHECK(found_flip);
    }
}

TEST_CASE("xyzac-trt equals LinuxCNC's xyzac-trt inverse, both rotation senses") {
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> U(-1, 1);
    for (int conventional : {0, 1}) {
        for (int trial = 0; trial < 20; ++trial) {
            const double xr = 30 * U(rng), yr = 30 * U(rng), zr = 30 * U(rng), dy = 10 * U(rng), dz = 20 * U(rng), dt = 5 * U(rng);
            const Machine m = machine("xyzac-trt", {{"x_rot_point", xr}, {"y_rot_point", yr}, {"z_rot_point", zr}, {"y_offset", dy},
                                                    {"z_offset", dz}, {"tool_offset", dt}, {"conventional", double(conventional)}});
            const Kinematics k(m);
            for (int i = 0; i < 25; ++i) {
                const double a = 100 * U(rng), c = 400 * U(rng);
                const double s = conventional ? -1.0 : 1.0;
                const double ar = rad(s * a), cr = rad(s * c);
                const Eigen::Vector3d p(40 * U(rng), 40 * U(rng), 40 * U(rng));
                std::vector<double> q(m.joints.size(), 0.0);
                q[joint(m, 'A')] = a;
                q[joint(m, 'C')] = c;
                REQUIRE(k.solve_position(p, q).ok());
                // LinuxCNC trtfuncs xyzacKinematicsInverse, with dz = z-offset + tool-offset.
                const double DZ = dz + dt;
                const double X = std::cos(cr) * (p.x() - xr) - std::sin(cr) * (p.y() - yr) + xr;
                const double Y = std::sin(cr) * std::cos(ar) * (p.x() - xr) + std::cos(cr) * std::cos(ar) * (p.y() - yr) -
                                 std::sin(ar) * (p.z() - zr) - std::cos(ar) * dy + std::sin(ar) * DZ + dy + yr;
                const double Z = std::sin(cr) * std::sin(ar) * (p.x() - xr) + std::cos(cr) * std::sin(ar) * (p.y() - yr) +
                                 std::cos(ar) * (p.z() - zr) - std::sin(ar) * dy - std::cos(ar) * DZ + DZ + zr;
                CHECK(q[joint(m, 'X')] == doctest::Approx(X).epsilon(1e-12));
                CHECK(q[joint(m, 'Y')] == doctest::Approx(Y).epsilon(1e-12));
                CHECK(q[joint(m, 'Z')] == doctest::Approx(Z).epsilon(1e-12));
            }
        }
    }
}

TEST_CASE("FK o IK and IK o FK round trips to 1e-9 on every shipped machine") {
    for (const auto& [name, path] : bundled_machines()) {
        CAPTURE_BINDING(name);
        const Machine m = load_machine(path);
        const Kinematics k(m);
        std::mt19937 rng(std::hash<std::string>{}(name) & 0xffff);
        int ik_fk = 0, fk_ik = 0;
        for (int i = 0; i < 3000; ++i) {
            // IK o FK: joints -> pose -> joints, starting from those joints: the same joints back.
            const auto q = random_joints(m, rng);
            const Pose pose = k.forward(q);
            std::vector<double> q2;
            const auto r = k.inverse(pose, q, q2);
            REQUIRE_MESSAGE(r.ok(), r.message);
            for (std::size_t j = 0; j < q.size(); ++j) CHECK(std::abs(q2[j] - q[j]) < 1e-9);
            ++ik_fk;
            // FK o IK: a pose solved from another start (possibly the other solution, other turns)
            // must still reproduce the pose exactly.
            const auto start = random_joints(m, rng);
            std::vector<double> q3;
            if (k.inverse(pose, start, q3).ok()) {
                const Pose back = k.forward(q3);
                CHECK((back.tip - pose.tip).norm() < 1e-9);
                CHECK((back.axis - pose.axis).norm() < 1e-9);
                ++fk_ik;
            }
        }
        CHECK(ik_fk == 3000);
        CHECK(fk_ik > 1000);  // the rest left the linear travel: a refused pose, not a wrong one
    }
}

TEST_CASE("a tool axis on a rotary axis keeps that joint where it was") {
    const Machine m = machine("pentarod");
    const Kinematics k(m);
    std::vector<double> prev(m.joints.size(), 0.0), q;
    prev[joint(m, 'C')] = 123.4;
    prev[joint(m, 'A')] = 20;
    REQUIRE(k.inverse({{0, 0, 10}, {0, 0, 1}}, prev, q).ok());
    CHECK(q[joint(m, 'C')] == 123.4);
    CHECK(std::abs(q[joint(m, 'A')]) < 1e-12);
}

TEST_CASE("unreachable orientations and limits are refused with a reason") {
    const Machine m = machine("addin4");
    const Kinematics k(m);
    std::vector<double> prev(m.joints.size(), 0.0), q;
    auto r = k.inverse({{10, 10, 10}, Eigen::Vector3d(0.3, 0, 1).normalized()}, prev, q);
    CHECK(r.status == IkStatus::Unreachable);
    CHECK(r.message.find("reach") != std::string::npos);

    const Machine p = machine("pentarod", {{"a_min", 0.0}});
    const Kinematics kp(p);
    // With A limited to 0..90 a vector below the horizon is out of reach of the limits.
    r = kp.inverse({{0, 0, 10}, Eigen::Vector3d(0.2, 0.1, -1).normalized()}, std::vector<double>(p.joints.size(), 0.0), q);
    CHECK(r.status == IkStatus::OutOfLimits);
    CHECK(r.message.find("limits") != std::string::npos);
    // With A in 0..90 the only solution of a tilted vector has A >= 0.
    REQUIRE(kp.inverse({{0, 0, 10}, Eigen::Vector3d(0.3, -0.2, 1).normalized()}, std::vector<double>(p.joints.size(), 0.0), q).ok());
    CHECK(q[p.joint_index('A')] > 0);
}

TEST_CASE("rotary choice: nearest the previous angle, 360-degree turns on unbounded axes, inside limits") {
    const Machine m = machine("pentarod");
    const Kinematics k(m);
    const int A = joint(m, 'A'), C = joint(m, 'C');
    std::vector<double> prev(m.joints.size(), 0.0), q;
    prev[A] = 30;
    prev[C] = 710;  // two turns on: the answer stays near 710, not at -10
    const double c = -10, a = 30;
    const Eigen::Vector3d u(std::sin(rad(a)) * std::sin(rad(c)), std::sin(rad(a)) * std::cos(rad(c)), std::cos(rad(a)));
    REQUIRE(k.inverse({{0, 0, 5}, u}, prev, q).ok());
    CHECK(q[C] == doctest::Approx(710).epsilon(1e-12));
    CHECK(q[A] == doctest::Approx(30).epsilon(1e-12));
    // From the other side of the pole the equivalent (-A, C + 180) is nearer.
    prev[A] = -30;
    prev[C] = 170;
    REQUIRE(k.inverse({{0, 0, 5}, u}, prev, q).ok());
    CHECK(q[A] == doctest::Approx(-30).epsilon(1e-12));
    CHECK(q[C] == doctest::Approx(170).epsilon(1e-12));

    // rw2's A is bounded at +-168: from A = 160, a target of 200 (= -160) must go the long way round.
    const Machine r = machine("rw2");
    const Kinematics kr(r);
    std::vector<double> rp(r.joints.size(), 0.0);
    rp[joint(r, 'A')] = 160;
    rp[joint(r, 'B')] = 30;
    const double A2 = 200, B2 = 30;
    const Eigen::Vector3d u2(std::sin(rad(B2)) * std::cos(rad(A2)), -std::sin(rad(B2)) * std::sin(rad(A2)), std::cos(rad(B2)));
    REQUIRE(kr.inverse({{100, 100, 10}, u2}, rp, q).ok());
    CHECK(q[joint(r, 'A')] >= -168);
    CHECK(q[joint(r, 'A')] <= 168);
    CHECK((kr.forward(q).axis - u2).norm() < 1e-9);
}

TEST_CASE("the machine's reach bounds every lever arm and every shift inside the limits, on every shipped machine") {
    // The motion stage clears whole moves with the reach and no FK: it must hold wherever the
    // joints can be (linear joints inside their limits, rotaries anywhere), tilted plates too.
    const std::map<std::string, std::map<std::string, double>> tilted = {
        {"wpi5", {{"rho", 1.7}, {"psi", -2.3}, {"sx", 0.4}, {"sy", -1.1}, {"sz", 0.7}}},
        {"pentarod", {{"a_offset", 2.9}, {"cx", 1.3}, {"cy", -0.8}}},
    };
    for (const auto& [name, path] : bundled_machines()) {
        for (const int variant : {0, 1}) {
            if (variant == 1 && !tilted.count(name)) continue;
            CAPTURE_BINDING(name);
            const Machine m = variant == 1 ? load_machine(path, tilted.at(name)) : load_machine(path);
            const Kinematics k(m);
            REQUIRE(k.path_bound().has_reach());
            std::mt19937 rng(std::hash<std::string>{}(name) & 0xff);
            std::uniform_real_distribution<double> U(0, 1);
            double tightest = 0;  // the largest arm found over its reach
            for (int i = 0; i < 20000; ++i) {
                std::vector<double> qa(m.joints.size()), qb(m.joints.size());
                for (std::size_t j = 0; j < qa.size(); ++j) {
                    const Joint& J = m.joints[j];
                    const double lo = J.bounded() ? J.min : -720, hi = J.bounded() ? J.max : 720;
                    qa[j] = lo + (hi - lo) * U(rng);
                    // A rounding-sized step, or a larger one, kept inside the limits.
                    qb[j] = std::clamp(qa[j] + (2 * U(rng) - 1) * (i % 2 ? 0.0005 : 0.5), lo, hi);
                }
                const auto end = k.path_end(qa.data());
                for (int a = 0; a < 8; ++a) {
                    CHECK(end.arm[a] <= k.path_bound().reach().arm[a] + 1e-9);
                    if (k.path_bound().reach().arm[a] > 0) tightest = std::max(tightest, end.arm[a] / k.path_bound().reach().arm[a]);
                }
                CHECK(end.lever_arm <= k.path_bound().reach().lever_arm + 1e-9);
                CHECK((k.forward(qb).tip - end.pose.tip).norm() <= k.path_bound().reach_shift(qa.data(), qb.data()) + 1e-9);
            }
            // A bound that is not far out, where the tip is off the rotary axes at all (addin4's
            // nozzle turns about its own tip).
            if (k.path_bound().reach().lever_arm > 1 && tightest > 0) CHECK(tightest > 0.3);
            MESSAGE(name << ": reach " << k.path_bound().reach().lever_arm << " mm, largest arm found " << tightest << " of it");
        }
    }
}

TEST_CASE("the tool axis's bound holds for turns of any size on every shipped machine") {
    // The planner's pole check clears a stretch of a joint-linear turn with it, where the
    // turntable may swing by a half turn or more: sampled at 400 points, the axis stays within
    // the bound (scaled by 4 t (1 - t)) of the chord between its ends, for turns up to 300 degrees.
    for (const auto& [name, path] : bundled_machines()) {
        CAPTURE_BINDING(name);
        const Machine m = load_machine(path);
        const Kinematics k(m);
        std::mt19937 rng(std::hash<std::string>{}(name) & 0xfff);
        std::uniform_real_distribution<double> U(0, 1);
        double closest = 0;  // the largest sampled deviation over its bound: how tight it gets
        for (int i = 0; i < 600; ++i) {
            const double scale = std::pow(10.0, -1.0 + 2.5 * U(rng));  // 0.1 .. 30 times the span below
            std::vector<double> qa(m.joints.size()), qb(m.joints.size());
            for (std::size_t j = 0; j < qa.size(); ++j) {
                qa[j] = -180 + 360 * U(rng);
                qb[j] = qa[j] + (2 * U(rng) - 1) * scale * 10.0;
            }
            const double bound = k.path_bound().axis_path_bound(qa.data(), qb.data());
            const Eigen::Vector3d ua = k.forward(qa).axis, ub = k.forward(qb).axis;
            std::vector<double> q(qa.size());
            for (int s = 1; s < 400; ++s) {
                const double t = s / 400.0;
                for (std::size_t j = 0; j < q.size(); ++j) q[j] = qa[j] + t * (qb[j] - qa[j]);
                const double dev = (k.tool_axis(q) - (ua + t * (ub - ua))).norm();
                CHECK(dev <= 4 * t * (1 - t) * bound + 1e-15);
                if (bound > 0) closest = std::max(closest, dev / (4 * t * (1 - t) * bound));
            }
        }
        if (k.rotary_joints().size() == 2) CHECK(closest > 0.2);  // not a bound that clears nothing
    }
}

namespace {

// A random start inside the machine's limits (an unbounded rotary within two turns) and a step
// from it of up to `scale` times 10 degrees (rotary) or 20 mm (linear) for each joint; none when
// scale is 0.
void random_step(const Machine& m, std::mt19937& rng, double scale, std::vector<double>& qa, std::vector<double>& qb) {
    std::uniform_real_distribution<double> U(0, 1);
    qa.resize(m.joints.size());
    qb.resize(m.joints.size());
    for (std::size_t j = 0; j < qa.size(); ++j) {
        const Joint& J = m.joints[j];
        const double lo = J.bounded() ? J.min : -720, hi = J.bounded() ? J.max : 720;
        qa[j] = lo + (hi - lo) * U(rng);
        qb[j] = scale == 0 ? qa[j] : qa[j] + (2 * U(rng) - 1) * scale * (J.rotary ? 10.0 : 20.0);
    }
}

}  // namespace

TEST_CASE("the joint-path bound's shorter path equals its general one bit for bit on every shipped machine") {
    for (const auto& [name, path] : bundled_machines()) {
        CAPTURE_BINDING(name);
        const Machine m = load_machine(path);
        const Kinematics k(m);
        std::mt19937 rng(std::hash<std::string>{}(name) & 0xffff);
        std::uniform_real_distribution<double> U(0, 1);
        int differ = 0;
        for (int i = 0; i < 3000; ++i) {
            const double scale = std::pow(10.0, -3.0 + 3.5 * U(rng));
            std::vector<double> qa, qb;
            random_step(m, rng, i % 7 == 0 ? 0.0 : scale, qa, qb);
            const auto a = k.path_end(qa.data());
            const auto fast = k.path_bound().joint_path_bound(a, qa.data(), qb.data());
            const auto general = k.path_bound().joint_path_bound_general(a, qa.data(), qb.data());
            if (std::memcmp(&fast.tip, &general.tip, sizeof fast.tip) != 0 || std::memcmp(&fast.axis, &general.axis, sizeof fast.axis) != 0) ++differ;
        }
        CHECK(differ == 0);
    }
}

TEST_CASE("the joint-path bound holds against dense sampling of the path on every shipped machine") {
    // The firmware moves every joint at a constant rate from qa to qb: the tip and the tool axis
    // (sampled at 400 points by FK) must stay within the bound of the chords between their ends.
    for (const auto& [name, path] : bundled_machines()) {
        CAPTURE_BINDING(name);
        const Machine m = load_machine(path);
        const Kinematics k(m);
        std::mt19937 rng(std::hash<std::string>{}(name) & 0xffff);
        std::uniform_real_distribution<double> U(0, 1);
        int bounded = 0, over = 0;  // over: samples past their bound (counted, not one CHECK each)
        std::string first_over;
        const int cases = sampled(1500);
        for (int i = 0; i < cases; ++i) {
            // Steps from small (a printing move) to large (a travel turn): up to 0.3 .. 30 degrees.
            const double scale = std::pow(10.0, -1.5 + 2.0 * U(rng));
            std::vector<double> qa, qb;
            random_step(m, rng, scale, qa, qb);
            const auto a = k.path_end(qa.data());
            const auto bound = k.path_bound().joint_path_bound(a, qa.data(), qb.data());
            const Pose pa = k.forward(qa), pb = k.forward(qb);
            CHECK((a.pose.tip - pa.tip).norm() < 1e-12);
            if (!std::isfinite(bound.tip)) continue;
            ++bounded;
            double tip = 0, axis = 0;
            std::vector<double> q(qa.size());
            for (int s = 1; s < 400; ++s) {
                const double t = s / 400.0;
                for (std::size_t j = 0; j < q.size(); ++j) q[j] = qa[j] + t * (qb[j] - qa[j]);
                const Pose p = k.forward(q);
                const double tip_t = (p.tip - (pa.tip + t * (pb.tip - pa.tip))).norm();
                const double axis_t = (p.axis - (pa.axis + t * (pb.axis - pa.axis))).norm();
                tip = std::max(tip, tip_t);
                axis = std::max(axis, axis_t);
                // Away from the middle the bound shrinks by 4 t (1 - t) (the motion stage clears
                // its outer samples with that).
                if (!(tip_t <= 4 * t * (1 - t) * bound.tip + 1e-12) || !(axis_t <= 4 * t * (1 - t) * bound.axis + 1e-15)) {
                    if (over++ == 0)
                        first_over = "case " + std::to_string(i) + " t " + std::to_string(t) + ": tip " + std::to_string(tip_t) + " of " +
                                     std::to_string(bound.tip) + ", axis " + std::to_string(axis_t) + " of " + std::to_string(bound.axis);
                }
            }
            CHECK(tip <= bound.tip + 1e-12);
            CHECK(axis <= bound.axis + 1e-15);
        }
        CHECK_MESSAGE(over == 0, first_over);
        CHECK(bounded > cases * 2 / 3);
    }
    // Useful where it is used: a printing move on rw2 (half a degree, a third of a millimetre)
    // is bounded well inside the default 0.01 mm.
    const Machine rw2 = machine("rw2");
    const Kinematics k(rw2);
    std::vector<double> qa = {100, 100, 20, 30, -25}, qb = {100.2, 100.25, 20.05, 30.5, -25.1};
    const auto bound = k.path_bound().joint_path_bound(k.path_end(qa.data()), qa.data(), qb.data());
    CHECK(bound.tip < 0.005);
    // Tight where the split needs it: a turn of the head's A alone (rw2's 300-degree lines, split
    // into a few degrees each) is bounded by the sagitta of the tip's own circle about A, not by
    // the farther B axis nor by X and Y, which carry the head at constant speed. Measured against
    // 400-point sampling, the bound is at most a tenth above it (it was 3 to 4 times before).
    for (const double turn : {1.0, 4.0, 10.0}) {
        CAPTURE(turn);
        std::vector<double> a = {100, 100, 20, 30, 12}, b = {100 + 0.4 * turn, 100 - 0.3 * turn, 20, 30 + turn, 12};
        const auto tight = k.path_bound().joint_path_bound(k.path_end(a.data()), a.data(), b.data());
        const Pose pa = k.forward(a), pb = k.forward(b);
        double worst = 0;
        std::vector<double> q(a.size());
        for (int s = 1; s < 400; ++s) {
            const double t = s / 400.0;
            for (std::size_t j = 0; j < q.size(); ++j) q[j] = a[j] + t * (b[j] - a[j]);
            worst = std::max(worst, (k.forward(q).tip - (pa.tip + t * (pb.tip - pa.tip))).norm());
        }
        CHECK(worst <= tight.tip);
        CHECK(tight.tip <= 1.1 * worst);
    }
}

namespace {

// The chain walk as Eigen's own products write it: the reference the scalar walk in
// chain.cpp must equal to the last bit (the split's decisions, and so the output, hang on it).
void eigen_chain(const std::vector<ChainElement>& chain, const std::vector<double>& q, Eigen::Matrix3d& R, Eigen::Vector3d& t,
                 std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>>& lines) {
    R.setIdentity();
    t.setZero();
    for (const auto& e : chain) {
        switch (e.kind) {
            case ChainElement::Kind::Fixed:
                t += R * e.fixed.translation();
                R = R * e.fixed.linear();
                break;
            case ChainElement::Kind::Linear: {
                const Eigen::Vector3d d = R * e.axis;
                t += d * q[std::size_t(e.joint)];
                break;
            }
            case ChainElement::Kind::Rotary: {
                lines.push_back({t + R * e.point, (R * e.axis).normalized()});
                const Eigen::Matrix3d Rj = Eigen::AngleAxisd(q[std::size_t(e.joint)] * (kPi / 180.0), e.axis).toRotationMatrix();
                t += R * (e.point - Rj * e.point);
                R = R * Rj;
                break;
            }
        }
    }
}

bool same_bits(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
    return std::memcmp(a.data(), b.data(), sizeof(double) * 3) == 0;
}

// The closed form of a two-turn table (Kinematics::has_two_turns) against the chain's products:
// equal to rounding, not to the bit. Tips and lever arms in mm (at most a few hundred here: some
// 1e-13 of rounding), unit vectors' components.
constexpr double kRoundingMm = 1e-9, kRoundingUnit = 1e-12;
bool within(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double tol) { return (a - b).cwiseAbs().maxCoeff() <= tol; }

}  // namespace

TEST_CASE("forward kinematics equals Eigen's products of the chain bit for bit on every shipped machine (a two-turn table to rounding)") {
    // Tilted plates and offsets too (wpi5's rho and psi, pentarod's A offset and C centre), so the
    // fixed rotations in the chains are not the identity.
    const std::map<std::string, std::map<std::string, double>> tilted = {
        {"wpi5", {{"rho", 1.7}, {"psi", -2.3}, {"sx", 0.4}, {"sy", -1.1}, {"sz", 0.7}}},
        {"pentarod", {{"a_offset", 2.9}, {"cx", 1.3}, {"cy", -0.8}}},
    };
    for (const auto& [name, path] : bundled_machines()) {
        // 0: as shipped; 1: tilted (where the machine has such parameters); 2: every axis and
        // fixed rotation of the chains turned to a random direction, so every product sums three
        // non-zero terms and the order of the sums shows.
        // 3 to 8 (pentarod): its shape with turns about other coordinate axes (forward's
        // closed form), signs and directions at random.
        for (const int variant : {0, 1, 2, 3, 4, 5, 6, 7, 8}) {
            if (variant == 1 && !tilted.count(name)) continue;
            if (variant >= 3 && name != "pentarod") continue;
            CAPTURE_BINDING(name);
            CAPTURE(variant);
            Machine m = variant == 1 ? load_machine(path, tilted.at(name)) : load_machine(path);
            std::mt19937 rng(std::hash<std::string>{}(name) & 0xffff);
            std::uniform_real_distribution<double> U(0, 1);
            if (variant == 2) turn_at_random(m, rng);
            if (variant >= 3) {
                const int k1 = (variant - 3) / 2, k2 = (k1 + 1 + (variant - 3) % 2) % 3;
                m = two_turns(m, k1, k2, int(U(rng) * 16), rng);
            }
            const Kinematics k(m);
            int differ = 0;
            for (int i = 0; i < sampled(20000); ++i) {
                const std::vector<double> q = random_joints(m, rng);
                Eigen::Matrix3d Rp, Rt;
                Eigen::Vector3d tp, tt;
                std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> lines;
                eigen_chain(m.part_chain, q, Rp, tp, lines);
                eigen_chain(m.tool_chain, q, Rt, tt, lines);
                const Eigen::Vector3d tip = Rp.transpose() * (tt - tp);
                const Eigen::Vector3d axis = (Rp.transpose() * (Rt * m.tool_axis)).normalized();
                double lever = 0;
                for (const auto& [point, dir] : lines) {
                    const Eigen::Vector3d d = tt - point;
                    lever = std::max(lever, (d - dir * dir.dot(d)).norm());
                }
                const Pose p = k.forward(q);
                const auto end = k.path_end(q.data());
                if (k.has_two_turns()) {
                    if (!within(p.tip, tip, kRoundingMm) || !within(p.axis, axis, kRoundingUnit) || !same_bits(k.tool_axis(q), p.axis) ||
                        !same_bits(end.pose.tip, p.tip) || !(std::abs(end.lever_arm - lever) <= kRoundingMm))
                        ++differ;
                } else if (!same_bits(p.tip, tip) || !same_bits(p.axis, axis) || !same_bits(k.tool_axis(q), axis) || !same_bits(end.pose.tip, tip) ||
                           std::memcmp(&end.lever_arm, &lever, sizeof lever) != 0)
                    ++differ;
                // The position solve's tool axis (the planner keeps it for the next move's pole
                // check): the same bits; it moves only the linear joints.
                std::vector<double> solved = q;
                Eigen::Vector3d solved_axis;
                // (Not on a polar machine: where the absent joint would leave its slack, as a tip moved
                // off the radial plane makes it, the solve turns C too: PolarTurn::solve.)
                if (!k.is_polar() && k.solve_position(tip + Eigen::Vector3d(U(rng) - 0.5, U(rng) - 0.5, U(rng) - 0.5), solved, &solved_axis).ok() &&
                    !(k.has_two_turns() ? same_bits(solved_axis, p.axis) : same_bits(solved_axis, axis)))
                    ++differ;
            }
            CHECK(differ == 0);
        }
    }
}

TEST_CASE("the position solve without a part chain equals the general products with the part frame") {
    // A machine whose part chain is empty (rw2) skips the part walk and the products with its
    // identity rotation. Against the same machine with a part chain that changes nothing but
    // a shift far below every tip's last bit (so the general products run, Rp the identity):
    // the same linear joints and tool axis on random poses (== allows only a zero's sign).
    int machines = 0;
    for (const auto& [name, path] : bundled_machines()) {
        const Machine m = load_machine(path);
        if (!m.part_chain.empty()) continue;
        ++machines;
        CAPTURE_BINDING(name);
        Machine general = m;
        ChainElement nudge;
        nudge.kind = ChainElement::Kind::Fixed;
        nudge.fixed.translation() = Eigen::Vector3d(1e-300, 0, 0);
        general.part_chain.push_back(nudge);
        const Kinematics fast(m), slow(general);
        std::mt19937 rng(17);
        std::uniform_real_distribution<double> U(0, 1);
        int differ = 0;
        for (int i = 0; i < 20000; ++i) {
            const std::vector<double> q = random_joints(m, rng);
            const Eigen::Vector3d tip(400 * U(rng) - 200, 400 * U(rng) - 200, 400 * U(rng) - 200);
            std::vector<double> qa = q, qb = q;
            Eigen::Vector3d aa, ab;
            const bool oka = fast.solve_position(tip, qa, &aa).ok(), okb = slow.solve_position(tip, qb, &ab).ok();
            if (oka != okb || qa != qb || aa != ab) ++differ;
        }
        CHECK(differ == 0);
    }
    CHECK(machines > 0);
}

TEST_CASE("the position solve's own end is the FK at its solution, and near_end bounds the FK at every rounding of it") {
    // The motion stage bounds a move's printed end from the solve's end instead of an FK: the
    // solve's pose and lever arms must be the FK's, and near_end's slacks must cover the FK at
    // joints moved from the solution (by the printed rounding, and by more). Every shipped
    // machine as shipped and with every axis turned at random, and two layouts built here from
    // pentarod's joints in which linear joints carry axis lines (the solve moves those lines):
    // Y under the trunnion (part chain Y, A, C) and a head whose Z rides on a tilt (tool chain
    // X, Y, A, Z; part chain C).
    std::mt19937 rng(20261126);
    std::uniform_real_distribution<double> U(0, 1);
    std::vector<std::pair<std::string, Machine>> cases;
    for (const auto& [name, path] : bundled_machines()) {
        cases.emplace_back(name, load_machine(path));
        Machine turned = load_machine(path);
        turn_at_random(turned, rng);
        cases.emplace_back(name + " turned", turned);
    }
    const Machine pentarod = machine("pentarod");
    const int X = joint(pentarod, 'X'), Y = joint(pentarod, 'Y'), Z = joint(pentarod, 'Z'), A = joint(pentarod, 'A'), C = joint(pentarod, 'C');
    auto linear = [](int j, Eigen::Vector3d axis) {
        ChainElement e;
        e.kind = ChainElement::Kind::Linear;
        e.joint = j;
        e.axis = axis;
        return e;
    };
    auto rotary = [](int j, Eigen::Vector3d axis, Eigen::Vector3d point) {
        ChainElement e;
        e.kind = ChainElement::Kind::Rotary;
        e.joint = j;
        e.axis = axis;
        e.point = point;
        return e;
    };
    Machine bed = pentarod;  // the trunnion rides on the Y bed
    bed.part_chain = {linear(Y, -Eigen::Vector3d::UnitY()), rotary(A, Eigen::Vector3d::UnitX(), {0, 0, -20}),
                      rotary(C, Eigen::Vector3d::UnitZ(), {3, -2, 0})};
    bed.tool_chain = {linear(X, Eigen::Vector3d::UnitX()), linear(Z, Eigen::Vector3d::UnitZ())};
    cases.emplace_back("built: Y under the trunnion", bed);
    Machine head = pentarod;  // Z rides on the tilting head
    head.part_chain = {rotary(C, Eigen::Vector3d::UnitZ(), {0, 0, 0})};
    head.tool_chain = {linear(X, Eigen::Vector3d::UnitX()), linear(Y, Eigen::Vector3d::UnitY()),
                       rotary(A, Eigen::Vector3d::UnitX(), {0, 5, 40}), linear(Z, Eigen::Vector3d::UnitZ())};
    cases.emplace_back("built: Z on the tilt", head);

    int given = 0;
    double printed_slack = 0;  // the largest tip slack of a printed rounding on pentarod as shipped
    for (const auto& [name, m] : cases) {
        CAPTURE_BINDING(name);
        const Kinematics k(m);
        int wrong = 0, loose = 0;
        for (int i = 0; i < 2000; ++i) {
            std::vector<double> q = random_joints(m, rng);
            const Eigen::Vector3d tip = k.forward(q).tip + Eigen::Vector3d(U(rng) - 0.5, U(rng) - 0.5, U(rng) - 0.5);
            Kinematics::SolvedEnd end;
            if (!k.solve_position(tip, q, nullptr, &end).ok() || !end.valid) continue;
            ++given;
            const Kinematics::PathEnd fk = k.path_end(q.data());
            bool same = end.q == q && (end.end.pose.tip - fk.pose.tip).norm() < 1e-9 && (end.end.pose.axis - fk.pose.axis).norm() < 1e-12 &&
                        std::abs(end.end.lever_arm - fk.lever_arm) < 1e-9 && end.end.tip_slack == 0 && end.end.axis_slack == 0;
            for (int a = 0; a < 8; ++a) same = same && std::abs(end.end.arm[a] - fk.arm[a]) < 1e-9;
            if (!same) ++wrong;
            // Joints moved from the solution: each by up to half a printed unit, then by more.
            for (const double step : {0.0005, 0.01, 0.5}) {
                std::vector<double> moved = q;
                for (double& v : moved) v += step * (2 * U(rng) - 1);
                Kinematics::PathEnd near;
                if (!k.path_bound().near_end(end, moved.data(), near)) {
                    ++loose;
                    continue;
                }
                const Kinematics::PathEnd there = k.path_end(moved.data());
                bool holds = (there.pose.tip - near.pose.tip).norm() <= near.tip_slack + 1e-9 &&
                             (there.pose.axis - near.pose.axis).norm() <= near.axis_slack + 1e-12 && there.lever_arm <= near.lever_arm + 1e-9;
                for (int a = 0; a < 8; ++a) holds = holds && there.arm[a] <= near.arm[a] + 1e-9;
                if (!holds) ++wrong;
                if (name == "pentarod" && step == 0.0005) printed_slack = std::max(printed_slack, near.tip_slack);
            }
        }
        CHECK(wrong == 0);
        CHECK(loose == 0);  // every machine here has limits on its linear joints: a reach
    }
    // Pentarod and the built layouts take the general solve, which gives its end (a machine
    // with a fixed Jacobian, rw2's, does not); a printed rounding's slack stays far below the
    // 0.01 mm tolerance, or the bound would be of no use.
    CHECK(given >= 4 * 1500);
    CHECK(printed_slack > 0);
    CHECK(printed_slack < 0.005);
    MESSAGE("largest tip slack of a printed rounding on pentarod: " << printed_slack << " mm");
}

TEST_CASE("the bounds' angle helpers are safe against acos and asin, and tight for small turns") {
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> U(0, 1);
    // Below about 1e-15 in the squared angle the dot product's own rounding decides (d within an
    // ulp of 1): both sides are then that small, far under the chord limit's margin (1e-12 of a
    // chord of about 0.017 for a degree), so the checks allow it.
    constexpr double kFloor = 1e-15;
    int unsafe = 0, loose = 0, unsafe_chord = 0;
    for (int i = 0; i < 200000; ++i) {
        // Angles from 1e-9 to 120 degrees, spread over their orders of magnitude.
        const double phi = std::pow(10.0, -9 + 11.3 * U(rng)) * kPi / 180.0;
        if (phi > 2.1) continue;
        const Eigen::Vector3d a = Eigen::Vector3d(U(rng) - 0.5, U(rng) - 0.5, U(rng) - 0.5).normalized();
        const Eigen::Vector3d n = a.cross(Eigen::Vector3d(U(rng) - 0.5, U(rng) - 0.5, U(rng) - 0.5)).normalized();
        const Eigen::Vector3d b = std::cos(phi) * a + std::sin(phi) * n;
        const double d = a.dot(b), exact = std::acos(std::clamp(d, -1.0, 1.0));
        const double bound = turn_squared_at_most(d);
        if (!(bound >= exact * exact - kFloor) || bound < 0) ++unsafe;
        if (phi < 0.1 && !(bound <= exact * exact * (1 + phi * phi / 4) + kFloor)) ++loose;
        if (d <= 0 && std::isfinite(bound)) ++unsafe;
        // A chord below chord_within(limit) is within the limit, by asin.
        const double limit = 180.0 * U(rng);
        const double c = chord_within(limit) * U(rng);
        if (!(2.0 * std::asin(0.5 * c) * 180.0 / kPi <= limit)) ++unsafe_chord;
    }
    CHECK(unsafe == 0);
    CHECK(loose == 0);
    CHECK(unsafe_chord == 0);
    // At the limit itself the chord is the limit's own, short by about 1e-12 of it (for the
    // small limits the split uses; near 180 degrees asin's slope makes that more of the angle).
    for (const double limit : {0.01, 0.97, 1.0, 45.0}) {
        const double c = chord_within(limit);
        CHECK(2.0 * std::asin(0.5 * c) * 180.0 / kPi <= limit);
        CHECK(2.0 * std::asin(0.5 * c) * 180.0 / kPi > limit * (1 - 1e-11));
    }
    CHECK(2.0 * std::asin(0.5 * chord_within(179.0)) * 180.0 / kPi <= 179.0);
    CHECK(chord_within(0) == 0);
    CHECK(chord_within(-1) == 0);
    CHECK(chord_within(180) == 0);
    CHECK(std::isinf(turn_squared_at_most(0.0)));
    CHECK(std::isinf(turn_squared_at_most(-0.5)));
    CHECK(turn_squared_at_most(1.0) == 0);
    CHECK(turn_squared_at_most(std::nextafter(1.0, 2.0)) == 0);  // a unit vectors' dot product rounded past 1
}

TEST_CASE("AngleLimit's verdicts are the acos's own, near the limit and far from it") {
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> U(0, 1);
    const double limits[] = {1e-6, 1e-3, 0.485, 0.5, 0.97, 1.0, 2.0, 45.0, 90.0, 179.9, 0.0, -1.0, 180.0, 200.0};
    for (const double limit : limits) {
        CAPTURE(limit);
        const AngleLimit test(limit);
        const double c = std::cos(rad(limit));
        std::vector<double> dots = {1.0, -1.0, 0.0, 1.0 + 1e-15, -1.0 - 1e-15, std::nan(""), c};
        for (int i = 0; i < 20000; ++i) {
            dots.push_back(2 * U(rng) - 1);
            dots.push_back(c + (2 * U(rng) - 1) * 1e-11);  // in the window and just outside it
            dots.push_back(c + (2 * U(rng) - 1) * 1e-15);
            dots.push_back(1.0 - std::ldexp(double(i % 64), -53));  // the last doubles below 1
            double d = c;
            for (int k = 0; k < i % 40; ++k) d = std::nextafter(d, i % 2 ? 2.0 : -2.0);  // ulps from the cosine
            dots.push_back(d);
        }
        // Unit vectors at angles near the limit, as the planner compares them.
        for (int i = 0; i < 20000; ++i) {
            const Eigen::Vector3d a = Eigen::Vector3d(U(rng) - 0.5, U(rng) - 0.5, U(rng) - 0.5).normalized();
            const Eigen::Vector3d n = a.cross(Eigen::Vector3d(U(rng) - 0.5, U(rng) - 0.5, U(rng) - 0.5)).normalized();
            const double angle = rad(limit + (2 * U(rng) - 1) * 1e-9);
            dots.push_back(a.dot((std::cos(angle) * a + std::sin(angle) * n).normalized()));
        }
        int differ = 0;
        for (const double d : dots) {
            const double exact = angle_of_dot(d);
            if (test.below(d) != (exact < limit) || test.above(d) != (exact > limit)) ++differ;
        }
        CHECK(differ == 0);
    }
}

TEST_CASE("least_dot_below gives the acos's verdict on every double near 1, for limits of a few ulps") {
    // The planner's exact-start test (1e-6 degrees) as `dot >= least`: right only if no double
    // below the least passing one passes again. Every double within 1e-12 of 1 (AngleLimit takes
    // the acos there; beyond, its own reason holds), random dots, and the clamped and NaN ones.
    std::mt19937 rng(13);
    std::uniform_real_distribution<double> U(-1, 1);
    for (const double limit : {1e-6, 3e-7, 2e-6, 4e-6}) {
        CAPTURE(limit);
        const double least = least_dot_below(limit);
        REQUIRE(least <= 1.0);
        int differ = 0, passed = 0;
        auto check = [&](double d) {
            const bool pass = angle_of_dot(d) < limit;
            passed += pass;
            if ((d >= least) != pass) ++differ;
        };
        for (double d = 1.0 + 1e-12; d >= 1.0 - 1e-12; d = std::nextafter(d, 0.0)) check(d);
        for (int i = 0; i < 100000; ++i) check(U(rng));
        for (const double d : {2.0, -2.0, std::nan(""), 0.0, -0.0}) check(d);
        CHECK(differ == 0);
        CHECK(passed > 0);
    }
    CHECK(std::isnan(least_dot_below(1e-5)));  // not a limit of a few ulps (137 doubles pass)
    CHECK(std::isnan(least_dot_below(0.0)));
}

TEST_CASE("atan2 is odd in y to the last bit, as the orientation solve's second tilt assumes") {
    // orientation_solutions takes the second solution's tilt as the first's negated when its
    // atan2 terms are the first's with y negated.
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> U(-1, 1);
    std::uniform_int_distribution<int> E(-60, 60);
    int differ = 0;
    auto check = [&](double y, double x) {
        const double a = std::atan2(y, x), b = -std::atan2(-y, x);
        if (std::memcmp(&a, &b, sizeof a) != 0) ++differ;
    };
    for (int i = 0; i < 400000; ++i) {
        check(U(rng), U(rng));  // unit vectors' terms
        check(std::ldexp(U(rng), E(rng)), std::ldexp(U(rng), E(rng)));
        check(std::ldexp(U(rng), -1070), U(rng));  // subnormal y
    }
    for (const double x : {1.0, -1.0, 0.0, -0.0, 1e-300, -1e-300})
        for (const double y : {0.0, -0.0, 1.0, 1e-300, 5e-324}) check(y, x);
    CHECK(differ == 0);
}

TEST_CASE("both orientation solutions reach the asked axis on every shipped machine, the second's turn half a turn from the first where its terms are negated") {
    // The second solution's first angle is taken half a turn from the first's (opposite_angle)
    // where its atan2 terms are the first's negated (pentarod's A/C table): each solution's FK
    // gives the asked axis, on random axes; on pentarod the two are (A, C) and (-A, C + 180).
    std::mt19937 rng(12);
    std::uniform_real_distribution<double> U(-1, 1);
    int checked = 0, bad = 0;
    for (const auto& [name, path] : bundled_machines()) {
        CAPTURE_BINDING(name);
        const Machine m = load_machine(path);
        const Kinematics k(m);
        const auto& rot = k.rotary_joints();
        if (rot.size() != 2) continue;
        for (int i = 0; i < 20000; ++i) {
            const Eigen::Vector3d axis = Eigen::Vector3d(U(rng), U(rng), U(rng)).normalized();
            const auto sol = k.orientation_solutions(axis);
            for (int b = 0; b < sol.count; ++b) {
                if (std::isnan(sol.angle[b][0]) || std::isnan(sol.angle[b][1])) continue;
                std::vector<double> q(m.joints.size(), 0.0);
                q[std::size_t(rot[0])] = sol.angle[b][0];
                q[std::size_t(rot[1])] = sol.angle[b][1];
                if (!within(k.tool_axis(q), axis, 1e-9)) ++bad;
                ++checked;
            }
            if (name == "pentarod" && sol.count == 2) {
                const int a = rot[0] == joint(m, 'A') ? 0 : 1, c = 1 - a;
                if (!(std::abs(sol.angle[0][a] + sol.angle[1][a]) <= 1e-9 && std::abs(std::abs(wrap180(sol.angle[0][c] - sol.angle[1][c])) - 180) <= 1e-9))
                    ++bad;
            }
        }
    }
    CHECK(bad == 0);
    CHECK(checked > 100000);
}

TEST_CASE("the orientation solve's shortcut equals its general path bit for bit, on every shipped machine and random axes") {
    // The shortcut (two rotaries along coordinate axes) leaves out the products with the axes'
    // zero entries; it must give the general path's bits, signed zeros and NaNs included, or
    // leave the axis to it. Machines: as shipped, tilted (fixed rotations that are not the
    // identity, a tool axis off the coordinate axes), and with random coordinate rotary axes of
    // either sign (their zero entries of either sign too). Axes: random, the machine's own at
    // random joints and at whole quarter turns (its poles), and vectors built from zeros of
    // both signs, ones, tiny and random numbers.
    const std::map<std::string, std::map<std::string, double>> tilted = {
        {"wpi5", {{"rho", 1.7}, {"psi", -2.3}}},
        {"pentarod", {{"a_offset", 2.9}, {"cx", 1.3}, {"cy", -0.8}}},
    };
    std::mt19937 rng(23);
    std::uniform_real_distribution<double> U(0, 1);
    std::uniform_int_distribution<int> pick(0, 2), coin(0, 1);
    int with_shortcut = 0, answered = 0, asked = 0;
    for (const auto& [name, path] : bundled_machines()) {
        for (int variant = 0; variant < 42; ++variant) {
            if (variant == 1 && !tilted.count(name)) continue;
            CAPTURE_BINDING(name);
            CAPTURE(variant);
            Machine m = variant == 1 ? load_machine(path, tilted.at(name)) : load_machine(path);
            if (variant >= 2) {
                auto coordinate = [&] {
                    Eigen::Vector3d w(coin(rng) ? 0.0 : -0.0, coin(rng) ? 0.0 : -0.0, coin(rng) ? 0.0 : -0.0);
                    w[pick(rng)] = coin(rng) ? 1.0 : -1.0;
                    return w;
                };
                auto unit = [&] { return Eigen::Vector3d(U(rng) - 0.5, U(rng) - 0.5, U(rng) - 0.5).normalized(); };
                for (auto* chain : {&m.part_chain, &m.tool_chain})
                    for (auto& e : *chain) {
                        if (e.kind == ChainElement::Kind::Rotary) e.axis = coordinate();
                        else if (e.kind == ChainElement::Kind::Fixed && coin(rng))
                            e.fixed.linear() = Eigen::AngleAxisd(U(rng) * 6, unit()).toRotationMatrix();
                    }
                m.tool_axis = coin(rng) ? coordinate() : unit();
            }
            std::unique_ptr<Kinematics> made;
            try {
                made = std::make_unique<Kinematics>(m);
            } catch (const MachineError&) {
                continue;  // parallel rotary axes
            }
            const Kinematics& k = *made;
            if (name == "pentarod" && variant == 0) CHECK(k.orientation_shortcut().on());
            if (!k.orientation_shortcut().on()) continue;
            ++with_shortcut;
            std::vector<Eigen::Vector3d> axes;
            for (int i = 0; i < 400; ++i) {
                axes.push_back(Eigen::Vector3d(U(rng) - 0.5, U(rng) - 0.5, U(rng) - 0.5).normalized());
                axes.push_back(k.forward(random_joints(m, rng)).axis);
                std::vector<double> q = random_joints(m, rng);
                for (const int j : k.rotary_joints()) q[std::size_t(j)] = 90.0 * std::uniform_int_distribution<int>(-4, 4)(rng);
                axes.push_back(k.forward(q).axis);
                const double parts[] = {0.0, -0.0, 1.0, -1.0, 1e-300, -5e-324, U(rng) - 0.5, 1e-9 * (U(rng) - 0.5)};
                std::uniform_int_distribution<int> part(0, 7);
                axes.push_back(Eigen::Vector3d(parts[part(rng)], parts[part(rng)], parts[part(rng)]));
                // Near a pole (the tool axis at rotaries zero), and a few ulps off an exact axis.
                const Eigen::Vector3d pole = k.forward(std::vector<double>(m.joints.size(), 0.0)).axis;
                axes.push_back(pole + 1e-7 * (U(rng) - 0.5) * Eigen::Vector3d(U(rng), U(rng), U(rng)));
                // At the distance where a joint turns free (1e-7), within a millionth of it.
                const Eigen::Vector3d side = pole.cross(Eigen::Vector3d(U(rng) - 0.5, U(rng) - 0.5, U(rng) - 0.5)).normalized();
                axes.push_back(pole + 1e-7 * (1 + 2e-6 * (U(rng) - 0.5)) * side);
                axes.push_back(Eigen::Vector3d(std::nextafter(1.0, 2.0), std::ldexp(U(rng) - 0.5, -52), -0.0));
            }
            const double inf = std::numeric_limits<double>::infinity(), nan = std::nan("");
            for (const Eigen::Vector3d& a : {Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(-0.0, 0, -0.0), Eigen::Vector3d(inf, 0, 1),
                                             Eigen::Vector3d(nan, 1, 0), Eigen::Vector3d(1e200, 1e200, 1e200)})
                axes.push_back(a);
            int differ = 0;
            for (const Eigen::Vector3d& a : axes) {
                const Kinematics::Solutions general = k.orientation_solutions_general(a);
                Kinematics::Solutions fast;
                ++asked;
                if (k.orientation_shortcut().solve(a, fast)) ++answered;
                else fast = general;
                const Kinematics::Solutions used = k.orientation_solutions(a);
                const Kinematics::Solutions* got[] = {&fast, &used};
                for (const Kinematics::Solutions* s : got) {
                    bool same = s->count == general.count && same_bits(s->axis, general.axis);
                    for (int b = 0; b < general.count && same; ++b)
                        same = std::memcmp(s->angle[b], general.angle[b], sizeof(double) * k.rotary_joints().size()) == 0;
                    if (!same) ++differ;
                }
            }
            CHECK(differ == 0);
        }
    }
    CHECK(with_shortcut > 20);
    // The shortcut answers nearly every axis itself (else this test would hold little).
    CHECK(answered > asked / 2);
    MESSAGE("orientation shortcut: " << with_shortcut << " machines, " << answered << " of " << asked << " axes answered");
}

TEST_CASE("pentarod's closed-form solve is Grutle's pseudo code 4.1: machine XYZ = R_x(A) R_z(C) p") {
    // The source's transform written out here on its own (Grutle, Oslo 2015): the position solve
    // gives it, forward() inverts it, and the tool axis is (sin A sin C, sin A cos C, cos A), on
    // random tips and angles across A's range and several turns of C.
    const Machine m = machine("pentarod");
    const Kinematics k(m);
    REQUIRE(k.has_two_turns());
    const int X = joint(m, 'X'), Y = joint(m, 'Y'), Z = joint(m, 'Z'), A = joint(m, 'A'), C = joint(m, 'C');
    std::mt19937 rng(41);
    std::uniform_real_distribution<double> U(-1, 1);
    int bad = 0;
    for (int i = 0; i < 100000; ++i) {
        const Eigen::Vector3d p(80 * U(rng), 80 * U(rng), 60 * U(rng));
        std::vector<double> q(m.joints.size(), 0.0);
        q[std::size_t(A)] = 90 * U(rng);
        q[std::size_t(C)] = 1000 * U(rng);
        REQUIRE(k.solve_position(p, q).ok());
        const double a = q[std::size_t(A)] * kPi / 180, c = q[std::size_t(C)] * kPi / 180;
        const double x1 = std::cos(c) * p.x() - std::sin(c) * p.y(), y1 = std::sin(c) * p.x() + std::cos(c) * p.y();  // R_z(C) p
        const Eigen::Vector3d want(x1, std::cos(a) * y1 - std::sin(a) * p.z(), std::sin(a) * y1 + std::cos(a) * p.z());  // R_x(A)
        const Eigen::Vector3d got(q[std::size_t(X)], q[std::size_t(Y)], q[std::size_t(Z)]);
        const Pose back = k.forward(q);
        const Eigen::Vector3d axis(std::sin(a) * std::sin(c), std::sin(a) * std::cos(c), std::cos(a));
        if (!within(got, want, kRoundingMm) || !within(back.tip, p, kRoundingMm) || !within(back.axis, axis, kRoundingUnit)) ++bad;
    }
    CHECK(bad == 0);
}

TEST_CASE("the position solve at a chosen orientation solution takes its cosines and sines from the solve's terms, to rounding") {
    // orient_within_limits reports which solution the rotaries took; the solve then reads the
    // rotaries' cosines and sines from that solution's atan2 terms instead of calling sincos. On
    // every two-turn machine shipped and pentarod's shape about other axes, random tool axes from
    // random previous joints (several turns of a multi-turn joint): the same joints as the solve
    // without the report, to rounding; and the report names a solution for nearly every axis.
    std::mt19937 rng(77);
    std::uniform_real_distribution<double> U(0, 1);
    std::vector<std::pair<std::string, Machine>> cases;
    for (const auto& [name, path] : bundled_machines()) cases.emplace_back(name, load_machine(path));
    for (int k1 = 0; k1 < 3; ++k1)
        for (int k2 = 0; k2 < 3; ++k2)
            if (k1 != k2) cases.emplace_back("pentarod's shape " + std::to_string(k1) + std::to_string(k2), two_turns(machine("pentarod"), k1, k2, int(U(rng) * 16), rng));
    int machines = 0, total = 0;
    for (const auto& [name, m] : cases) {
        CAPTURE_BINDING(name);
        const Kinematics k(m);
        if (!k.has_two_turns() || !k.orientation_shortcut().on()) continue;
        ++machines;
        int asked = 0, named = 0, differ = 0;
        for (int i = 0; i < 20000; ++i) {
            const std::vector<double> previous = random_joints(m, rng);
            const Eigen::Vector3d axis = Eigen::Vector3d(U(rng) - 0.5, U(rng) - 0.5, U(rng) - 0.5).normalized();
            const Eigen::Vector3d tip(100 * U(rng) - 50, 100 * U(rng) - 50, 100 * U(rng) - 50);
            const auto solutions = k.orientation_solutions(axis);
            std::vector<double> q = previous;
            ChosenSolution chosen;
            if (!orient_within_limits(m, k.rotary_joints(), solutions, previous, previous, q, &chosen).ok()) continue;
            ++asked;
            if (chosen.branch < 0) continue;
            ++named;
            std::vector<double> with = q, without = q;
            Eigen::Vector3d axis_with, axis_without;
            const IkResult a = k.solve_position(tip, with, &axis_with, nullptr, chosen);
            const IkResult b = k.solve_position(tip, without, &axis_without);
            bool ok = a.status == b.status && within(axis_with, axis_without, kRoundingUnit) && within(axis_with, axis, 1e-9);
            for (std::size_t j = 0; j < q.size(); ++j) ok = ok && std::abs(with[j] - without[j]) <= kRoundingMm;
            if (!ok) ++differ;
        }
        CHECK(differ == 0);
        CHECK(named >= asked * 9 / 10);  // (a shape whose tool axis reaches few axes may have none)
        MESSAGE(name << ": " << named << " of " << asked << " solves at a named solution");
        total += named;
    }
    CHECK(machines >= 7);  // pentarod's six shapes and the shipped two-turn tables
    CHECK(total > 100000);
}

TEST_CASE("the position solve in scalars equals its Eigen general path bit for bit, on random machines and joints") {
    // solve_position's general path (walk, then the scalar products, determinant and inverse)
    // against solve_position_general (the same walk, then Eigen's products): every output to the
    // last bit (a two-turn table's closed form: to rounding, kRoundingMm), with and without the
    // axis and the end, on every shipped machine as shipped, with
    // its calibration offsets, turned at random, and with linear joints moved into the part chain
    // (a direction from the part chain alone, and from both).
    std::mt19937 rng(915);
    std::uniform_real_distribution<double> U(0, 1);
    std::vector<std::pair<std::string, Machine>> cases;
    for (const auto& [name, path] : bundled_machines()) {
        cases.emplace_back(name, load_machine(path));
        for (int t = 0; t < 4; ++t) {
            Machine turned = load_machine(path);
            turn_at_random(turned, rng);
            cases.emplace_back(name + " turned", turned);
        }
    }
    cases.emplace_back("pentarod offsets", machine("pentarod", {{"a_offset", 2.9}, {"cx", 1.3}, {"cy", -0.8}}));
    const Machine pentarod = machine("pentarod");
    for (int t = 0; t < 4; ++t) {
        Machine bed = pentarod;  // Y moved to the front of the part chain (and, in half, kept in the tool chain too)
        const int Y = joint(pentarod, 'Y');
        ChainElement y;
        y.kind = ChainElement::Kind::Linear;
        y.joint = Y;
        y.axis = t == 0 ? Eigen::Vector3d(0, -1, 0) : Eigen::Vector3d(U(rng) - 0.5, U(rng) - 0.5, U(rng) - 0.5);
        bed.part_chain.insert(bed.part_chain.begin(), y);
        if (t % 2 == 0)
            bed.tool_chain.erase(std::remove_if(bed.tool_chain.begin(), bed.tool_chain.end(), [&](const ChainElement& e) { return e.joint == Y; }),
                                 bed.tool_chain.end());
        cases.emplace_back("pentarod Y in the part chain", bed);
    }
    for (int k1 = 0; k1 < 3; ++k1)  // every pair of axes, with signs and directions drawn at random
        for (int k2 = 0; k2 < 3; ++k2)
            if (k1 != k2)
                for (int t = 0; t < 2; ++t)
                    cases.emplace_back("pentarod's shape, turns about axes " + std::to_string(k1) + " and " + std::to_string(k2),
                                       two_turns(pentarod, k1, k2, int(U(rng) * 16), rng));
    int compared = 0;
    for (const auto& [name, m] : cases) {
        CAPTURE_BINDING(name);
        const Kinematics k(m);
        // n doubles the same to the bit; for the closed form of a two-turn table, within `tol`
        // relative to the value past 1 (a random chain far from any real machine can put a linear
        // joint at 55 km, where two orders of the same sums differ by 1e-9 mm: 1e-14 of it).
        auto same_n = [&](const double* a, const double* b, std::size_t n, double tol) {
            if (!k.has_two_turns()) return std::memcmp(a, b, n * sizeof(double)) == 0;
            for (std::size_t i = 0; i < n; ++i)
                if (!(std::abs(a[i] - b[i]) <= tol * std::max(1.0, std::abs(b[i])))) return false;
            return true;
        };
        auto same = [&](const void* a, const void* b, std::size_t size) { return std::memcmp(a, b, size) == 0; };
        int differ = 0;
        for (int i = 0; i < sampled(3000); ++i) {
            const std::vector<double> q = random_joints(m, rng);
            const Eigen::Vector3d tip = i % 7 == 0 ? Eigen::Vector3d(400 * U(rng) - 200, 400 * U(rng) - 200, 400 * U(rng) - 200)
                                                   : k.forward(q).tip + Eigen::Vector3d(U(rng) - 0.5, U(rng) - 0.5, U(rng) - 0.5);
            for (const int ask : {0, 1, 2, 3}) {
                std::vector<double> qa = q, qb = q;
                Eigen::Vector3d aa(7, 7, 7), ab(7, 7, 7);
                Kinematics::SolvedEnd ea, eb;
                // A polar machine's solve may turn C (PolarTurn::solve), which the general path does not.
                if (k.is_polar()) continue;
                const IkResult ra = k.solve_position(tip, qa, ask & 1 ? &aa : nullptr, ask & 2 ? &ea : nullptr);
                const IkResult rb = k.solve_position_general(tip, qb, ask & 1 ? &ab : nullptr, ask & 2 ? &eb : nullptr);
                bool ok = ra.status == rb.status && ra.message == rb.message && qa.size() == qb.size() &&
                          same_n(qa.data(), qb.data(), qa.size(), kRoundingMm) && same_n(aa.data(), ab.data(), 3, kRoundingUnit) &&
                          ea.valid == eb.valid;
                if (ea.valid && eb.valid)
                    ok = ok && ea.q.size() == eb.q.size() && same_n(ea.q.data(), eb.q.data(), ea.q.size(), kRoundingMm) &&
                         same(ea.end.pose.tip.data(), eb.end.pose.tip.data(), 24) &&
                         same_n(ea.end.pose.axis.data(), eb.end.pose.axis.data(), 3, kRoundingUnit) &&
                         same_n(&ea.end.lever_arm, &eb.end.lever_arm, 1, kRoundingMm) && same_n(ea.end.arm, eb.end.arm, 8, kRoundingMm) &&
                         same(&ea.end.tip_slack, &eb.end.tip_slack, 8) && same(&ea.end.axis_slack, &eb.end.axis_slack, 8);
                if (!ok) ++differ;
                ++compared;
            }
        }
        CHECK(differ == 0);
    }
    CHECK(compared > sampled(100000));
}
