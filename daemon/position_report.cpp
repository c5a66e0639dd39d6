// SPDX-License-Identifier: GPL-3.0-or-later
#include "daemon/position_report.hpp"

#include <charconv>
#include <cmath>
#include <cstdio>

namespace xlate5 {

std::optional<Reported> read_position(const Machine& machine, std::string_view report, std::string& why) {
    // "X:7.00 Y:0.00 Z:0.00 A:10.00 B:5.00 E:0.00 Count X:560 …": the words before "Count".
    Reported r;
    r.q.assign(machine.joints.size(), 0.0);
    std::vector<bool> seen(machine.joints.size(), false);
    std::string_view words = report.substr(0, report.find("Count"));
    for (std::size_t i = 0; i + 1 < words.size(); ++i) {
        if (words[i + 1] != ':' || (i > 0 && words[i - 1] != ' ')) continue;
        std::string_view v = words.substr(i + 2);
        while (!v.empty() && v.front() == ' ') v.remove_prefix(1);
        const std::string_view token = v.substr(0, v.find(' '));
        double x = 0;
        const auto [end, ec] = std::from_chars(token.data(), token.data() + token.size(), x);
        const bool number = ec == std::errc() && end == token.data() + token.size() && std::isfinite(x);
        if (words[i] == 'E') {
            if (number) r.e = x;
            continue;
        }
        for (std::size_t j = 0; j < machine.joints.size(); ++j) {
            if (machine.joints[j].output != words[i]) continue;
            if (!number) {
                why = std::string("its ") + words[i] + " is '" + std::string(token) + "', not a number";
                return std::nullopt;
            }
            r.q[j] = x;
            seen[j] = true;
        }
    }
    for (std::size_t j = 0; j < machine.joints.size(); ++j)
        if (!seen[j]) {
            why = std::string("it has no ") + machine.joints[j].output;
            return std::nullopt;
        }
    machine.compensation.undo(r.q);
    return r;
}

std::string tool_space_position(const Machine& machine, const Kinematics& kin, const Eigen::Vector3d& program_offset,
                                const Reported& at) {
    // The nominal joints read_position took from the firmware's report -> tip and angles in the
    // part frame.
    const std::vector<double>& q = at.q;
    const Pose pose = kin.forward(q);
    const Eigen::Vector3d tip = pose.tip - program_offset;
    char buf[96];
    std::snprintf(buf, sizeof buf, "X:%.2f Y:%.2f Z:%.2f", tip.x(), tip.y(), tip.z());
    std::string out = buf;
    // E right after Z: OctoPrint 1.x reads M114 only as "X: Y: Z: E:" (docs/service.md); the
    // rotaries follow.
    if (at.e) {
        std::snprintf(buf, sizeof buf, " E:%.2f", *at.e);
        out += buf;
    }
    for (std::size_t j = 0; j < machine.joints.size(); ++j) {
        if (!machine.joints[j].rotary) continue;
        std::snprintf(buf, sizeof buf, " %c:%.2f", machine.joints[j].name, q[j]);
        out += buf;
    }
    return out;
}

}  // namespace xlate5
