// SPDX-License-Identifier: GPL-3.0-or-later
// `xlate5 calibrate fit|plate|offset|centre|pivots`: measurements in, machine-file values out
// (stage: command line; may call translators/calibration and the machine file reader/writer).
#pragma once
#include <CLI/CLI.hpp>
#include <memory>
#include <string>

#include "cli/errors.hpp"

namespace xlate5::cli {

struct CalibrateCommands {
    CLI::App *calibrate = nullptr, *fit = nullptr, *plate = nullptr, *offset = nullptr, *pivots = nullptr, *centre = nullptr;
    std::string fit_table, fit_joint = "X", fit_by = "A";
    int fit_order = 1;
    std::string plate_points, plate_out;
    std::string offset_points, offset_param, offset_out;
    std::string pivots_points, pivots_fit, pivots_out;
    std::string centre_points, centre_param, centre_out;
};

std::unique_ptr<CalibrateCommands> add_calibrate_commands(CLI::App& app);
// The exit code when a calibrate command ran, -1 when none was asked for.
int run_calibrate_commands(const CalibrateCommands& c, const Common& common);

}  // namespace xlate5::cli
