// SPDX-License-Identifier: GPL-3.0-or-later
// The firmware's M114 report, read in joint space and told to senders in tool space (stage:
// service middle; may call the kinematics and the machine). Pure text and arithmetic.
#pragma once
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>

#include "translators/kinematics/kinematics.hpp"
#include "translators/machine/machine.hpp"

namespace xlate5 {

// The joints (nominal: the machine's compensation undone) and E of a firmware's M114 report.
struct Reported {
    std::vector<double> q;
    std::optional<double> e;
};

// "X:7.00 Y:0.00 Z:0.00 A:10.00 B:5.00 E:0.00 Count X:560 …" read by the joints' firmware
// letters; nullopt, with why, when any of the machine's joints is missing or not a number.
std::optional<Reported> read_position(const Machine& machine, std::string_view report, std::string& why);

// The report as a sender expects it: "X: Y: Z:" the tip in the program frame (`program_offset`
// from the part frame), then E, then the rotary joints by their input letters.
std::string tool_space_position(const Machine& machine, const Kinematics& kin, const Eigen::Vector3d& program_offset,
                                const Reported& at);

}  // namespace xlate5
