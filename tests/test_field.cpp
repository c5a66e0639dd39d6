// The field's machines (machines/core-rtheta.toml, open5x.toml, voron-xyzac.toml, fullcontrol-xyzb.toml)
// against their projects' own transforms, each written out here from the project's code or
// configuration on its own, independently of the machine file: forward and inverse kinematics on
// many poses, and the projects' real joint-space files where the corpus has one.
#include <doctest/doctest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <random>
#include <sstream>
#include <string>

#include "helpers.hpp"
#include "translators/kinematics.hpp"
#include "translators/machine.hpp"

using namespace xlate5;
using xlate5::test::rad;

namespace {

Machine machine(const std::string& name, const std::map<std::string, double>& overrides = {}) {
    return load_machine(std::string(XLATE5_MACHINE_DIR_FOR_TESTS) + "/" + name + ".toml", overrides);
}

int joint(const Machine& m, char name) {
    const int j = m.joint_index(name);
    REQUIRE(j >= 0);
    return j;
}

double angle_diff(double a, double b) { return std::abs(wrap180(a - b)); }

// S4's cartesian_to_rtheta (Joshua Bird's S4_Slicer, 2025), without its travel lift: the joints
// it writes for a tip (x, y, z) in the part frame at tilt t (radians). C comes unwrapped, in
// (-180, 180].
struct Rtheta {
    double c, x, z, b;
};
Rtheta s4_joints(double x, double y, double z, double t, double offset) {
    double r = std::sqrt(x * x + y * y);
    const double theta = std::atan2(y, x);
    r += -std::sin(t) * offset;
    const double z_adj = z + (std::cos(t) - 1) * offset;
    return {theta * 180 / xlate5::test::kPi, r, z_adj, t * 180 / xlate5::test::kPi};
}

}  // namespace

TEST_CASE("core-rtheta is S4's cartesian_to_rtheta: FK and IK on random poses") {
    const Machine m = machine("core-rtheta");
    const Kinematics k(m);
    const double L = m.parameters.at("nozzle_offset");
    CHECK(L == 42);  // S4's NOZZLE_OFFSET
    const int X = joint(m, 'X'), Y = joint(m, 'Y'), Z = joint(m, 'Z'), B = joint(m, 'B'), C = joint(m, 'C');
    std::mt19937 rng(37);
    std::uniform_real_distribution<double> U(-1, 1);
    for (int i = 0; i < 20000; ++i) {
        // Tips off the bed's axis (S4's atan2 is undefined on it), tilts inside the limits.
        const double r0 = 2 + 60 * (U(rng) + 1) / 2, th = 179.9 * U(rng);
        const Eigen::Vector3d p(r0 * std::cos(rad(th)), r0 * std::sin(rad(th)), 40 * U(rng) + 40);
        const double t = rad(-60 + 70 * (U(rng) + 1) / 2);
        const Rtheta s = s4_joints(p.x(), p.y(), p.z(), t, L);
        // S4's tool axis: the nozzle leans in the radial plane, the holder toward the centre for t > 0.
        const Eigen::Vector3d u(-std::sin(t) * std::cos(rad(s.c)), -std::sin(t) * std::sin(rad(s.c)), std::cos(t));
        std::vector<double> q(m.joints.size(), 0.0);
        q[X] = s.x, q[Z] = s.z, q[B] = s.b, q[C] = s.c + 360.0 * std::round(U(rng) * 3);  // C may be any turn
        const Pose fk = k.forward(q);
        CHECK((fk.tip - p).norm() < 1e-9);
        CHECK((fk.axis - u).norm() < 1e-12);
        // IK from near S4's joints returns them, with the missing Y at 0.
        std::vector<double> prev = q, back;
        prev[B] += 0.5, prev[C] -= 1;
        REQUIRE(k.inverse({p, u}, prev, back).ok());
        CHECK(std::abs(back[X] - s.x) < 1e-9);
        CHECK(std::abs(back[Z] - s.z) < 1e-9);
        CHECK(std::abs(back[B] - s.b) < 1e-9);
        CHECK(std::abs(back[C] - q[C]) < 1e-9);
        CHECK(std::abs(back[Y]) < 1e-9);
    }
    // A tool axis that is not radial is beyond this machine: refused, never a move it cannot make.
    std::vector<double> q;
    const Eigen::Vector3d tangential(0, std::sin(rad(20)), std::cos(rad(20)));
    CHECK_FALSE(k.inverse({{30, 0, 5}, tangential}, m.home_joints(), q).ok());
}

TEST_CASE("core-rtheta: S4's own joint-space file goes through FK and back to the same poses, Y at 0") {
    if (xlate5::test::corpus_absent()) return;
    const Machine m = machine("core-rtheta");
    const Kinematics k(m);
    std::ifstream in(xlate5::test::corpus_dir() + "/s4/pi_3mm_side_paint_rtheta.gcode");
    REQUIRE(in);
    std::vector<double> q = m.home_joints(), back;
    std::string line;
    int moves = 0, other = 0;
    double worst = 0;
    while (std::getline(in, line)) {
        if (line.rfind("G01 ", 0) != 0 && line.rfind("G0 ", 0) != 0) continue;
        std::istringstream words(line.substr(line.find(' ')));
        std::string w;
        const std::vector<double> prev = q;
        while (words >> w) {
            if (w[0] == ';') break;
            const int j = m.joint_index(w[0]);
            if (j >= 0) q[std::size_t(j)] = std::stod(w.substr(1));
        }
        const Pose pose = k.forward(q);
        // The solve from the previous line's joints finds this line's (C on its own turn).
        REQUIRE_MESSAGE(k.inverse(pose, prev, back).ok(), line);
        const Pose again = k.forward(back);
        worst = std::max({worst, (again.tip - pose.tip).norm(), (again.axis - pose.axis).norm()});
        CHECK(std::abs(back[std::size_t(joint(m, 'Y'))]) < 1e-9);
        // Where the file's C jumps by more than a right angle (its travels), the other solution
        // (C + 180, -B, X on the far side) may be the nearer: the same pose, other joints.
        bool same = true;
        for (std::size_t j = 0; j < q.size(); ++j) same = same && std::abs(back[j] - q[j]) < 1e-6;
        if (!same) {
            ++other;
            CHECK_MESSAGE(angle_diff(back[std::size_t(joint(m, 'C'))], q[std::size_t(joint(m, 'C'))] + 180) < 1e-6, line);
            CHECK_MESSAGE(std::abs(back[std::size_t(joint(m, 'B'))] + q[std::size_t(joint(m, 'B'))]) < 1e-6, line);
        }
        ++moves;
    }
    MESSAGE(moves << " moves, " << other << " on the other solution");
    CHECK(moves > 5000);
    CHECK(other * 10 < moves);  // 182 of 5 094 here
    CHECK(worst < 1e-9);
}

TEST_CASE("fullcontrol-xyzb is FullControl's four-axis inverse kinematics, with and without b_offset_x") {
    for (const double bx : {0.0, 7.5}) {
        CAPTURE(bx);
        const Machine m = machine("fullcontrol-xyzb", {{"b_offset_x", bx}});
        const Kinematics k(m);
        const double bz = m.parameters.at("b_offset_z");
        const int X = joint(m, 'X'), Y = joint(m, 'Y'), Z = joint(m, 'Z'), B = joint(m, 'B');
        std::mt19937 rng(41);
        std::uniform_real_distribution<double> U(-1, 1);
        for (int i = 0; i < 20000; ++i) {
            const Eigen::Vector3d p(125 + 60 * U(rng), 105 + 50 * U(rng), 70 + 30 * U(rng));  // every joint inside its limits
            const double bdeg = 89.9 * U(rng), b = rad(bdeg);
            // FullControl's model2system, as its four-axis Point writes it.
            const double nx = -bx, nz = -bz;
            const double dx = -(nx * (1 - std::cos(b))) + nz * std::sin(b);
            const double dz = -(nz * (1 - std::cos(b))) + nx * -std::sin(b);
            std::vector<double> q(m.joints.size(), 0.0);
            q[X] = p.x() - dx, q[Y] = p.y(), q[Z] = p.z() - dz, q[B] = bdeg;
            const Pose fk = k.forward(q);
            CHECK((fk.tip - p).norm() < 1e-9);
            const Eigen::Vector3d u(std::sin(b), 0, std::cos(b));
            CHECK((fk.axis - u).norm() < 1e-12);
            std::vector<double> back;
            REQUIRE(k.inverse({p, u}, m.home_joints(), back).ok());
            for (std::size_t j = 0; j < q.size(); ++j) CHECK(std::abs(back[j] - q[j]) < 1e-9);
        }
        // A lean toward Y is out of this machine's reach.
        std::vector<double> back;
        CHECK_FALSE(k.inverse({{100, 100, 10}, Eigen::Vector3d(0, std::sin(rad(10)), std::cos(rad(10)))}, m.home_joints(), back).ok());
    }
}

TEST_CASE("voron-xyzac is the Voron-Trident-5-axis add-on's AC kinematics, at its pivot and another") {
    for (const double d : {0.0, 35.0}) {
        CAPTURE(d);
        const Machine m = machine("voron-xyzac", {{"a_pivot_z", d}});
        const Kinematics k(m);
        const int X = joint(m, 'X'), Y = joint(m, 'Y'), Z = joint(m, 'Z'), A = joint(m, 'A'), C = joint(m, 'C');
        std::mt19937 rng(43);
        std::uniform_real_distribution<double> U(-1, 1);
        int tested = 0;
        for (int i = 0; i < 20000; ++i) {
            // A build direction in the upper half (the add-on's acos gives A in 0..90).
            const double a = rad(89 * (U(rng) + 1) / 2), c = rad(179.9 * U(rng));
            const Eigen::Vector3d K(std::sin(a) * std::sin(c), std::sin(a) * std::cos(c), std::cos(a));
            const Eigen::Vector3d p(40 * U(rng), 40 * U(rng), 30 * (U(rng) + 1) / 2);
            // The add-on's calculate_inverse_kinematics and apply_visual_rotations.
            const double a_out = std::acos(K.z()), c_kin = std::atan2(K.x(), K.y()), c_out = -c_kin;
            const Eigen::Vector3d pivot(0, 0, d);
            const Eigen::Vector3d machine_p = Eigen::AngleAxisd(a_out, Eigen::Vector3d::UnitX()) *
                                                  (Eigen::AngleAxisd(c_kin, Eigen::Vector3d::UnitZ()) * (p - pivot)) + pivot;
            if (machine_p.z() < 0 || machine_p.z() > 131) continue;  // below the plate's reach (Z0 is the nozzle on it)
            ++tested;
            std::vector<double> prev = m.home_joints(), q;
            prev[A] = a_out * 180 / xlate5::test::kPi + 1, prev[C] = c_out * 180 / xlate5::test::kPi - 1;
            REQUIRE(k.inverse({p, K}, prev, q).ok());
            CHECK(std::abs(q[A] - a_out * 180 / xlate5::test::kPi) < 1e-9);
            CHECK(std::abs(q[C] - c_out * 180 / xlate5::test::kPi) < 1e-9);
            CHECK((Eigen::Vector3d(q[X], q[Y], q[Z]) - machine_p).norm() < 1e-9);
            const Pose fk = k.forward(q);
            CHECK((fk.tip - p).norm() < 1e-9);
            CHECK((fk.axis - K).norm() < 1e-12);
        }
        CHECK(tested > 5000);
    }
}

TEST_CASE("open5x: RepRapFirmware's U and V letters, and the A/C-table transform its file states") {
    // Open5x publishes no readable transform (a Grasshopper definition): what is checked is the
    // file's own statement, machine = R_x(U) R_z(V) (p - pivot) + pivot, written out here, and that
    // the firmware is sent U and V as its config.g maps them.
    const Machine m = machine("open5x");
    const Kinematics k(m);
    const int X = joint(m, 'X'), Y = joint(m, 'Y'), Z = joint(m, 'Z'), Uj = joint(m, 'U'), V = joint(m, 'V');
    CHECK(m.joints[std::size_t(Uj)].output == 'U');
    CHECK(m.joints[std::size_t(V)].output == 'V');
    const Eigen::Vector3d pivot(0, 0, m.parameters.at("u_pivot_z"));
    std::mt19937 rng(47);
    std::uniform_real_distribution<double> U(-1, 1);
    int tested = 0;
    for (int i = 0; i < 20000; ++i) {
        const double u_deg = 89 * U(rng), v_deg = 179.9 * U(rng);
        const Eigen::Vector3d p(30 * U(rng), 30 * U(rng), 20 * (U(rng) + 1) / 2);
        const Eigen::Vector3d mp = Eigen::AngleAxisd(rad(u_deg), Eigen::Vector3d::UnitX()) *
                                       (Eigen::AngleAxisd(rad(v_deg), Eigen::Vector3d::UnitZ()) * (p - pivot)) + pivot;
        if (mp.x() < -126 || mp.x() > 125 || mp.y() < -92.3 || mp.y() > 50 || mp.z() < -1 || mp.z() > 125) continue;
        ++tested;
        const Eigen::Vector3d axis(std::sin(rad(u_deg)) * std::sin(rad(v_deg)), std::sin(rad(u_deg)) * std::cos(rad(v_deg)), std::cos(rad(u_deg)));
        std::vector<double> q(m.joints.size(), 0.0);
        q[X] = mp.x(), q[Y] = mp.y(), q[Z] = mp.z(), q[Uj] = u_deg, q[V] = v_deg;
        const Pose fk = k.forward(q);
        CHECK((fk.tip - p).norm() < 1e-9);
        CHECK((fk.axis - axis).norm() < 1e-12);
        std::vector<double> prev = q, back;
        prev[Uj] += 1, prev[V] -= 1;
        REQUIRE(k.inverse({p, axis}, prev, back).ok());
        for (std::size_t j = 0; j < q.size(); ++j) CHECK(std::abs(back[j] - q[j]) < 1e-9);
    }
    CHECK(tested > 5000);
}

TEST_CASE("every bundled machine gives every joint its speed limit") {
    for (const auto& [name, path] : bundled_machines()) {
        CAPTURE_BINDING(name);
        const Machine m = load_machine(path);
        for (const Joint& j : m.joints) {
            CAPTURE(j.name);
            CHECK(j.max_feed > 0);
        }
    }
}

TEST_CASE("rw2's Z is held to the Ender 5 Pro's 5 mm/s: a fast Z move is written at F300") {
    // Andersons' head rides an Ender 5 Pro, whose Marlin allows Z 5 mm/s: a move planned at
    // F6000 along Z alone would take 0.5 s in xlate5's plan and 10 s on the printer.
    xlate5::test::TempDir dir;
    const auto in = dir.write("z.gcode", "G1 Z250 F6000\n");
    const auto out = dir.path / "out.gcode";
    const std::string cmd = std::string(XLATE5_BINARY) + " --machine rw2 -i " + xlate5::test::quote(in.string()) + " -o " +
                            xlate5::test::quote(out.string());
    REQUIRE(std::system(cmd.c_str()) == 0);
    const auto lines = xlate5::test::lines_of(xlate5::test::read(out));
    REQUIRE(lines.size() == 2);
    CHECK(xlate5::test::words_of(lines[1]).at('Z') == 250);
    CHECK(xlate5::test::words_of(lines[1]).at('F') == 300);  // Z alone: its limit (F6000 before)
}
