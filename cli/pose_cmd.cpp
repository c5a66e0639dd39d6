// SPDX-License-Identifier: GPL-3.0-or-later
// `xlate5 pose`: reads joint values or a tip and tool axis from the command line, calls
// Kinematics::forward or Kinematics::inverse and prints joints, tip and axis the same way for
// both, so one direction's output can be fed to the other (stage: command line).
#include "cli/pose_cmd.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <sstream>

#include "cli/options.hpp"
#include "translators/error.hpp"
#include "translators/kinematics/kinematics.hpp"
#include "translators/machine/machine.hpp"

namespace xlate5::cli {
namespace {

// Joint values and coordinates beyond this are typing mistakes, not machines (mm or degrees).
constexpr double kLargest = 1e6;

double parse_number(const std::string& text, const std::string& what) {
    const char* begin = text.c_str();
    char* end = nullptr;
    const double v = std::strtod(begin, &end);
    if (end == begin || *end != '\0' || !std::isfinite(v) || std::fabs(v) > kLargest)
        throw CLI::ValidationError(what, "expected a number from -1000000 to 1000000, got '" + text + "'");
    return v;
}

// "1,2,3" -> three numbers.
Eigen::Vector3d parse_triple(const std::string& text, const std::string& what) {
    std::vector<double> v;
    std::stringstream list(text);
    for (std::string field; std::getline(list, field, ',');) v.push_back(parse_number(field, what));
    if (v.size() != 3 || text.back() == ',') throw CLI::ValidationError(what, "expected three comma-separated numbers, got '" + text + "'");
    return {v[0], v[1], v[2]};
}

std::string joint_names(const Machine& m) {
    std::string names;
    for (const auto& j : m.joints) names += (names.empty() ? "" : ", ") + std::string(1, j.name);
    return names;
}

// The machine's home configuration with the JOINT=VALUE words applied.
std::vector<double> parse_joints(const Machine& m, const std::vector<std::string>& words) {
    auto q = m.home_joints();
    std::vector<bool> given(q.size(), false);
    for (const auto& w : words) {
        const auto eq = w.find('=');
        if (eq != 1 || !std::isalpha(static_cast<unsigned char>(w[0])))
            throw CLI::ValidationError("JOINT=VALUE", "expected a joint letter, '=' and a number (e.g. A=30), got '" + w + "'");
        const int i = m.joint_index(char(std::toupper(static_cast<unsigned char>(w[0]))));
        if (i < 0)
            throw CLI::ValidationError("JOINT=VALUE", std::string("machine ") + m.name + " has no joint " + w[0] + " (it has " + joint_names(m) + ")");
        if (given[std::size_t(i)]) throw CLI::ValidationError("JOINT=VALUE", std::string("joint ") + w[0] + " is given twice");
        given[std::size_t(i)] = true;
        q[std::size_t(i)] = parse_number(w.substr(2), w.substr(0, 1));
    }
    return q;
}

void print(const Machine& m, const std::vector<double>& q, const Pose& p) {
    std::printf("joints");
    for (std::size_t i = 0; i < q.size(); ++i) std::printf(" %c=%.4f", m.joints[i].name, q[i] == 0 ? 0.0 : q[i]);
    std::printf("\n");
    const auto z = [](double v) { return std::fabs(v) < 5e-7 ? 0.0 : v; };  // no "-0.000000"
    std::printf("tip    X=%.4f Y=%.4f Z=%.4f   (mm, part frame)\n", z(p.tip.x()), z(p.tip.y()), z(p.tip.z()));
    const double tilt = std::acos(std::clamp(p.axis.z(), -1.0, 1.0)) * 180.0 / M_PI;
    std::printf("axis   I=%.6f J=%.6f K=%.6f   (tip to holder, part frame; %.3f degrees from the plate's normal)\n", z(p.axis.x()),
                z(p.axis.y()), z(p.axis.z()), tilt);
    // Outside the limits is still a pose to look at, but the translation would refuse it.
    for (std::size_t i = 0; i < q.size(); ++i) {
        const auto& j = m.joints[i];
        if (j.bounded() && (q[i] < j.min - 1e-9 || q[i] > j.max + 1e-9))
            std::printf("note: %c=%.4f is outside its limits %s to %s\n", j.name, q[i], number_text(j.min).c_str(), number_text(j.max).c_str());
    }
}

}  // namespace

std::unique_ptr<PoseCommand> add_pose_command(CLI::App& app) {
    auto c = std::make_unique<PoseCommand>();
    c->pose = app.add_subcommand("pose",
                                 "the tip and tool axis at given joints (A=30 C=20 ...; joints not named stay at home), or with --tip "
                                 "the joints for a tip and tool axis: to check a machine file against a ruler");
    c->pose->add_option("joints", c->joints,
                        "joint values, e.g. X=10 A=30 (mm, degrees); with --tip, the configuration the nearest solution is chosen to")
        ->option_text("JOINT=VALUE ...");
    c->pose->add_option("--tip", c->tip, "tip position in the part frame, mm: print the joints that reach it")->option_text("X,Y,Z");
    c->pose->add_option("--axis", c->axis, with_default("with --tip: tool axis in the part frame (tip to holder; any length)", "0,0,1"))
        ->option_text("I,J,K");
    return c;
}

int run_pose_command(const PoseCommand& c, const Common& common) {
    if (!c.pose->parsed()) return -1;
    try {
        if (common.machine.empty()) throw CLI::ValidationError("--machine", "pose needs the machine (see 'xlate5 machines')");
        if (!c.axis.empty() && c.tip.empty()) throw CLI::ValidationError("--axis", "needs --tip (the joints for a tip and tool axis)");
        const auto machine = load_machine(common.machine, parse_sets(common.sets));
        const Kinematics kinematics(machine);
        const auto given = parse_joints(machine, c.joints);
        if (c.tip.empty()) {
            print(machine, given, kinematics.forward(given));
            return kOk;
        }
        Pose pose;
        pose.tip = parse_triple(c.tip, "--tip");
        const Eigen::Vector3d axis = c.axis.empty() ? Eigen::Vector3d::UnitZ() : parse_triple(c.axis, "--axis");
        if (axis.norm() < 1e-9) throw CLI::ValidationError("--axis", "the tool axis cannot be 0,0,0");
        pose.axis = axis.normalized();
        std::vector<double> q;
        if (const auto r = kinematics.inverse(pose, given, q); !r.ok()) {
            std::fprintf(stderr, "xlate5: pose: no joints reach tip %s, axis %s: %s\n", c.tip.c_str(),
                         c.axis.empty() ? "0,0,1" : c.axis.c_str(), r.message.c_str());
            return kInputError;
        }
        // Printed from the joints found, so what is shown is what they reach.
        print(machine, q, kinematics.forward(q));
        return kOk;
    } catch (...) {
        return exit_with(std::current_exception());
    }
}

}  // namespace xlate5::cli
