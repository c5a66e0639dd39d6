// SPDX-License-Identifier: GPL-3.0-or-later
// `xlate5 --machine M pose ...`: the machine file's geometry at one configuration, both ways:
// joints in, tip and tool axis out (forward kinematics), or a tip and tool axis in, joints out
// (the inverse the translation uses), so a machine file can be checked against a ruler
// (stage: command line; may call the machine file reader and translators/kinematics).
#pragma once
#include <CLI/CLI.hpp>
#include <memory>
#include <string>
#include <vector>

#include "cli/errors.hpp"

namespace xlate5::cli {

struct PoseCommand {
    CLI::App* pose = nullptr;
    std::vector<std::string> joints;  // JOINT=VALUE words
    std::string tip, axis;            // X,Y,Z and I,J,K (part frame)
};

std::unique_ptr<PoseCommand> add_pose_command(CLI::App& app);
// The exit code when `pose` ran, -1 when it was not asked for.
int run_pose_command(const PoseCommand& c, const Common& common);

}  // namespace xlate5::cli
