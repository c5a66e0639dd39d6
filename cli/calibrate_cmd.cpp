// SPDX-License-Identifier: GPL-3.0-or-later
// `xlate5 calibrate ...`: reads measurement tables, calls the fits in translators/calibration and
// prints (or writes into a copy of the machine file) what they give (stage: command line).
#include "cli/calibrate_cmd.hpp"

#include <algorithm>
#include <cctype>
#include <cstdlib>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <sstream>
#include <vector>

#include "cli/options.hpp"
#include "translators/machine/calibration.hpp"
#include "translators/pipeline/compensation.hpp"
#include "translators/error.hpp"
#include "translators/inputs/gcode_lexer.hpp"
#include "translators/machine/machine.hpp"
#include "translators/inputs/small_file.hpp"
#include "translators/pipeline/stream.hpp"

namespace xlate5::cli {
namespace {

// A calibrated copy of the machine file: the new values written in, checked to load, and never
// over the original.
int write_calibrated_copy(const Machine& m, const std::string& text, const std::map<std::string, double>& values,
                          const std::string& output) {
    if (std::filesystem::exists(output) && std::filesystem::equivalent(output, m.source_path)) {
        std::cerr << "xlate5: " << output << " is the machine file itself: write the calibrated copy elsewhere\n";
        return kUsage;
    }
    const std::string updated = set_parameters(text, m.source_path, values);
    (void)load_machine_text(updated, output);
    OutputSink sink(output);
    sink.write(updated);
    sink.commit();
    std::printf("wrote %s\n", output.c_str());
    return kOk;
}

// Rows of numbers from a small measurement file (at most kMaxMeasurementBytes): `columns`
// comma-separated numbers a line, each finite and within +-1e9 (the G-code lexer's bound), '#'
// comments and blank lines skipped. Prints "path:line:column: ..." and returns false on a bad line.
// A spreadsheet's header row before the first measurement ("angle,error", "x (mm), y (mm)"):
// `columns` fields, each starting with a letter and none a number ("inf" and "nan" are numbers
// to strtod, and are refused as data), so no row of measurements is ever taken for one.
bool header_row(const std::string& l, int columns) {
    int fields = 0;
    std::size_t at = 0;
    for (;;) {
        const std::size_t comma = l.find(',', at);
        std::string f = l.substr(at, comma == std::string::npos ? std::string::npos : comma - at);
        f.erase(0, std::min(f.size(), f.find_first_not_of(" \t\"")));
        if (f.empty() || !std::isalpha(static_cast<unsigned char>(f[0]))) return false;
        char* end = nullptr;
        (void)std::strtod(f.c_str(), &end);
        if (end != f.c_str()) return false;
        ++fields;
        if (comma == std::string::npos) break;
        at = comma + 1;
    }
    return fields == columns;
}

bool read_rows(const std::string& path, int columns, std::vector<std::vector<double>>& rows, int& exit_code) {
    std::string text;
    try {
        text = read_small_file(path, kMaxMeasurementBytes, "a measurement table");
    } catch (...) {
        exit_code = exit_with(std::current_exception());
        return false;
    }
    std::istringstream in(text);
    std::string l;
    for (int line = 1; std::getline(in, l); ++line) {
        if (auto h = l.find('#'); h != std::string::npos) l.resize(h);
        if (l.find_first_not_of(" \t\r") == std::string::npos) continue;
        if (auto r = l.find('\r'); r != std::string::npos && r + 1 == l.size()) l.pop_back();
        if (rows.empty() && header_row(l, columns)) continue;
        std::vector<double> row;
        std::size_t at = 0;  // where the field starts in the line
        std::string bad;
        for (;;) {
            const std::size_t comma = l.find(',', at);
            const std::string field = l.substr(at, comma == std::string::npos ? std::string::npos : comma - at);
            char* end = nullptr;
            const double v = std::strtod(field.c_str(), &end);
            while (end && (*end == ' ' || *end == '\t' || *end == '\r')) ++end;
            if (end == field.c_str() || (end && *end) || !std::isfinite(v)) {
                bad = "expected a number";
            } else if (std::abs(v) > kMaxNumber) {
                bad = "a number beyond +-1e9";
            }
            if (!bad.empty()) {
                const std::size_t skip = std::min(field.size(), field.find_first_not_of(" \t"));
                std::cerr << path << ":" << line << ":" << at + skip + 1 << ": " << bad << " (" << columns
                          << " comma-separated numbers a line)\n";
                exit_code = kInputError;
                return false;
            }
            row.push_back(v);
            if (comma == std::string::npos) break;
            at = comma + 1;
        }
        if (int(row.size()) != columns) {
            std::cerr << path << ":" << line << ":1: expected " << columns << " comma-separated numbers, got " << row.size() << "\n";
            exit_code = kInputError;
            return false;
        }
        rows.push_back(row);
    }
    return true;
}

// A fit that refuses its measurements: the reason and what to measure instead, naming the file.
int refuse(const std::string& path, const CalibrationError& e) {
    std::cerr << "xlate5: " << path << ": " << e.what() << "\n";
    return kInputError;
}

// calibrate fit: least-squares Fourier series through a measured table, printed as a
// [[compensation]] term with the residual, so a user can paste it into a machine file.
int calibrate_fit(const std::string& path, int order, const std::string& joint, const std::string& by) {
    std::vector<std::vector<double>> rows;
    int code = kOk;
    if (!read_rows(path, 2, rows, code)) return code;
    std::vector<double> angle, error;
    for (const auto& r : rows) angle.push_back(r[0]), error.push_back(r[1]);
    if (int(angle.size()) < 2 * order + 1) {
        std::cerr << "xlate5: " << path << ": " << angle.size() << " points cannot fit " << order << " harmonics (need " << 2 * order + 1 << ")\n";
        return kInputError;
    }
    double residual = 0, condition = 0;
    CompensationTerm t;
    try {
        t = fit_fourier(angle, error, order, residual, &condition);
    } catch (const CalibrationError& e) {
        return refuse(path, e);
    }
    std::printf("# fitted to %zu points of %s: largest residual %.4f mm (condition number %.3g)\n", angle.size(), path.c_str(), residual,
                condition);
    std::printf("[[compensation]]\njoint = \"%s\"\nby = \"%s\"\nfourier = { a0 = %.6f, cos = [", joint.c_str(), by.c_str(), t.a0);
    for (std::size_t k = 0; k < t.cosines.size(); ++k) std::printf("%s%.6f", k ? ", " : "", t.cosines[k]);
    std::printf("], sin = [");
    for (std::size_t k = 0; k < t.sines.size(); ++k) std::printf("%s%.6f", k ? ", " : "", t.sines[k]);
    std::printf("] }\n");
    return kOk;
}

// calibrate plate: a plane through the probed points, and the machine's rho and psi.
int calibrate_plate(const std::string& path, const std::string& machine_name, const std::string& output) {
    std::vector<std::vector<double>> rows;
    int code = kOk;
    if (!read_rows(path, 3, rows, code)) return code;
    std::vector<Eigen::Vector3d> points;
    for (const auto& r : rows) points.emplace_back(r[0], r[1], r[2]);
    if (points.size() < 3) {
        std::cerr << "xlate5: " << path << ": a plane needs at least 3 points, got " << points.size() << "\n";
        return kInputError;
    }
    PlateFit fit;
    try {
        fit = fit_plate(points);
    } catch (const CalibrationError& e) {
        return refuse(path, e);
    }
    std::printf("plate normal (%.6f, %.6f, %.6f) from %zu points, largest residual %.4f mm (condition number %.3g)\n", fit.normal.x(),
                fit.normal.y(), fit.normal.z(), points.size(), fit.residual, fit.condition);
    std::printf("rho = %.6f\npsi = %.6f\n", fit.rho, fit.psi);
    if (output.empty()) return kOk;
    if (machine_name.empty()) {
        std::cerr << "xlate5: calibrate plate -o needs --machine (the file to start from)\n";
        return kUsage;
    }
    try {
        const auto m = load_machine(machine_name);
        std::printf("was: rho = %.6f, psi = %.6f (%s)\n", m.parameters.count("rho") ? m.parameters.at("rho") : 0.0,
                    m.parameters.count("psi") ? m.parameters.at("psi") : 0.0, m.source_path.c_str());
        return write_calibrated_copy(m, read_machine_file(m.source_path), {{"rho", fit.rho}, {"psi", fit.psi}}, output);
    } catch (...) {
        return exit_with(std::current_exception());
    }
}

// calibrate offset / centre: shows what the fitted values change in the machine (old -> new) and,
// with -o, writes the calibrated copy. The measurements are absolute (joint space, machine frame),
// so the values replace the file's rather than adding to them.
int store_calibration(const char* command, const std::string& machine_name, const std::vector<std::pair<std::string, double>>& values,
                      const std::string& output, const std::map<std::string, double>& overrides) {
    try {
        if (values.empty()) {
            if (!output.empty())
                throw CLI::ValidationError("--param", std::string("calibrate ") + command + " -o needs --param (the machine parameter(s) to set)");
            return kOk;
        }
        if (machine_name.empty())
            throw CLI::ValidationError("--machine", std::string("calibrate ") + command + " --param needs --machine (the file to start from)");
        const auto m = load_machine(machine_name, overrides);
        std::map<std::string, double> set;
        for (const auto& [name, value] : values) {
            const auto it = m.parameters.find(name);
            if (it == m.parameters.end()) {
                std::string known;
                for (const auto& p : m.parameters) known += (known.empty() ? "" : ", ") + p.first;
                throw MachineError(m.source_path + ": [parameters] has no '" + name + "' (it has: " + (known.empty() ? "none" : known) + ")");
            }
            std::printf("%s: %.6f -> %.6f\n", name.c_str(), it->second, value);
            set[name] = value;
        }
        if (output.empty()) return kOk;
        return write_calibrated_copy(m, read_machine_file(m.source_path), set, output);
    } catch (...) {
        return exit_with(std::current_exception());
    }
}

// calibrate pivots: machine parameters by least squares from tips measured at known joints.
int calibrate_pivots(const CalibrateCommands& c, const Common& common) {
    try {
        if (common.machine.empty()) throw CLI::ValidationError("--machine", "calibrate pivots needs the machine to start from");
        const auto m = load_machine(common.machine, parse_sets(common.sets));
        std::vector<std::vector<double>> rows;
        int code = kOk;
        const int n = int(m.joints.size());
        if (!read_rows(c.pivots_points, n + 3, rows, code)) return code;
        std::vector<std::string> names;
        std::stringstream list(c.pivots_fit);
        for (std::string name; std::getline(list, name, ',');)
            if (!name.empty()) names.push_back(name);
        std::vector<std::vector<double>> joints;
        std::vector<Eigen::Vector3d> tips;
        for (const auto& r : rows) {
            joints.emplace_back(r.begin(), r.begin() + n);
            tips.emplace_back(r[std::size_t(n)], r[std::size_t(n + 1)], r[std::size_t(n + 2)]);
        }
        if (tips.size() * 3 < names.size()) {
            std::cerr << "xlate5: " << tips.size() << " measurements cannot fit " << names.size() << " parameters\n";
            return kInputError;
        }
        const std::string text = read_machine_file(m.source_path);
        ParameterFit fit;
        try {
            fit = fit_parameters(text, m.source_path, names, m.parameters, joints, tips);
        } catch (const CalibrationError& e) {
            return refuse(c.pivots_points, e);
        }
        for (const auto& name : names) std::printf("%s = %.6f   (was %.6f)\n", name.c_str(), fit.values.at(name), m.parameters.at(name));
        std::printf("largest residual %.4f mm over %zu measurements (condition number %.3g)\n", fit.residual, tips.size(), fit.condition);
        if (c.pivots_out.empty()) return kOk;
        std::map<std::string, double> values;
        for (const auto& name : names) values[name] = fit.values.at(name);
        return write_calibrated_copy(m, text, values, c.pivots_out);
    } catch (...) {
        return exit_with(std::current_exception());
    }
}

// calibrate offset (plate touches along Y) and calibrate centre (dots at several rotary angles).
int calibrate_offset_or_centre(const CalibrateCommands& c, const Common& common) {
    const bool offset = c.offset->parsed();
    std::vector<std::vector<double>> rows;
    int code = kOk;
    if (!read_rows(offset ? c.offset_points : c.centre_points, 2, rows, code)) return code;
    std::vector<Eigen::Vector2d> pts;
    for (const auto& r : rows) pts.emplace_back(r[0], r[1]);
    if (pts.size() < (offset ? 2u : 3u)) {
        std::cerr << "xlate5: need at least " << (offset ? 2 : 3) << " points, got " << pts.size() << "\n";
        return kInputError;
    }
    std::vector<std::pair<std::string, double>> values;
    const std::string& path = offset ? c.offset_points : c.centre_points;
    if (offset) {
        OffsetFit f;
        try {
            f = fit_rotary_offset(pts);
        } catch (const CalibrationError& e) {
            return refuse(path, e);
        }
        std::printf("rotary offset %.6f deg (atan of dZ/dY over %zu touches), plate Z at Y = 0: %.4f mm, largest residual %.4f mm "
                    "(condition number %.3g)\n",
                    f.offset_deg, pts.size(), f.z_error, f.residual, f.condition);
        if (!c.offset_param.empty()) values = {{c.offset_param, f.offset_deg}};
    } else {
        CircleFit f;
        try {
            f = fit_circle(pts);
        } catch (const CalibrationError& e) {
            return refuse(path, e);
        }
        std::printf("rotation centre (%.4f, %.4f), radius %.4f mm, largest residual %.4f mm over %zu dots (condition number %.3g)\n",
                    f.centre.x(), f.centre.y(), f.radius, f.residual, pts.size(), f.condition);
        if (!c.centre_param.empty()) {
            std::vector<std::string> names;
            std::stringstream list(c.centre_param);
            for (std::string name; std::getline(list, name, ',');) names.push_back(name);
            if (names.size() != 2 || names[0].empty() || names[1].empty() || names[0] == names[1])
                return exit_with(std::make_exception_ptr(
                    CLI::ValidationError("--param", "expected two parameter names, X,Y (e.g. cx,cy), got '" + c.centre_param + "'")));
            values = {{names[0], f.centre.x()}, {names[1], f.centre.y()}};
        }
    }
    try {
        return store_calibration(offset ? "offset" : "centre", common.machine, values, offset ? c.offset_out : c.centre_out,
                                 parse_sets(common.sets));
    } catch (...) {
        return exit_with(std::current_exception());
    }
}

}  // namespace

std::unique_ptr<CalibrateCommands> add_calibrate_commands(CLI::App& app) {
    auto c = std::make_unique<CalibrateCommands>();
    c->calibrate = app.add_subcommand("calibrate", "turn measurements into machine-file values");
    c->calibrate->require_subcommand(1);
    c->fit = c->calibrate->add_subcommand("fit", "fit a Fourier series to a measured error table (CSV: angle,error per line)");
    c->fit->add_option("table", c->fit_table, "CSV file: angle (degrees), error (mm) per line; '#' starts a comment")->required();
    c->fit->add_option("--order", c->fit_order, with_default("harmonics, 1 to 12", "1"))->check(whole_in(1, 12, ""))->option_text("N");
    c->fit->add_option("--joint", c->fit_joint, with_default("joint the error is taken off (for the printed [[compensation]] term)", "X"))
        ->option_text("LETTER");
    c->fit->add_option("--by", c->fit_by, with_default("rotary joint the error depends on", "A"))->option_text("LETTER");
    c->plate = c->calibrate->add_subcommand("plate", "plate tilt rho, psi from probed plate points (CSV: x,y,z per line, 3 or more)");
    c->plate->add_option("points", c->plate_points, "CSV file of probed points, machine frame, mm")->required();
    c->plate->add_option("-o,--output", c->plate_out, "write the machine file with rho and psi set here (never over the original)")
        ->option_text("FILE");
    c->offset = c->calibrate->add_subcommand("offset", "rotary zero offset from plate touches along Y (CSV: y,z per line; Grutle, Oslo 2015, eq. 5.5)");
    c->offset->add_option("points", c->offset_points, "CSV file of touches: Y, Z (mm), two or more, both sides of the axis")->required();
    c->offset->add_option("--param", c->offset_param, "machine parameter that holds the offset, e.g. a_offset (pentarod)")->option_text("NAME");
    c->offset->add_option("-o,--output", c->offset_out, "write the machine file with the offset set here (never over the original)")
        ->option_text("FILE");
    c->pivots = c->calibrate->add_subcommand("pivots", "machine parameters (link lengths, pivots) from tips measured at known joints");
    c->pivots->add_option("points", c->pivots_points, "CSV: the joints in the machine file's order, then the measured tip x,y,z (part frame, mm)")
        ->required();
    c->pivots->add_option("--fit", c->pivots_fit, "parameters to fit, comma-separated, e.g. la,lb")->required()->option_text("NAME,...");
    c->pivots->add_option("-o,--output", c->pivots_out, "write the machine file with the fitted values here (never over the original)")
        ->option_text("FILE");
    c->centre = c->calibrate->add_subcommand("centre", "rotation centre from dots at several rotary angles (CSV: x,y per line)");
    c->centre->add_option("points", c->centre_points, "CSV file of measured dot positions (mm), three or more")->required();
    c->centre->add_option("--param", c->centre_param,
                          "the two machine parameters that hold the centre, X then Y, e.g. cx,cy (pentarod) or wx,wy (koc5)")
        ->option_text("X,Y");
    c->centre->add_option("-o,--output", c->centre_out, "write the machine file with the centre set here (never over the original)")
        ->option_text("FILE");
    return c;
}

int run_calibrate_commands(const CalibrateCommands& c, const Common& common) {
    if (c.fit->parsed()) return calibrate_fit(c.fit_table, c.fit_order, c.fit_joint, c.fit_by);
    if (c.plate->parsed()) return calibrate_plate(c.plate_points, common.machine, c.plate_out);
    if (c.pivots->parsed()) return calibrate_pivots(c, common);
    if (c.offset->parsed() || c.centre->parsed()) return calibrate_offset_or_centre(c, common);
    return -1;
}

}  // namespace xlate5::cli
