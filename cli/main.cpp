// xlate5: the command line. Parses options, loads the machine, and runs the translation stages;
// the stages themselves live in translators/.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fcntl.h>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
#include <map>
#include <optional>
#include <string>
#include <unistd.h>

#include "cli/serve_cmd.hpp"
#include "translators/calibration.hpp"
#include "translators/compensation.hpp"
#include "translators/error.hpp"
#include "translators/kinematics.hpp"
#include "translators/machine.hpp"
#include "translators/stream.hpp"
#include "translators/translator.hpp"

#ifndef XLATE5_VERSION
#define XLATE5_VERSION "0.0.0"
#endif

namespace {

// Documented in the README; scripts rely on them.
enum Exit : int {
    kOk = 0,
    kInputError = 1,    // the G-code cannot be translated (file:line:column: message)
    kUsage = 2,         // bad command line
    kMachineError = 3,  // machine file missing or broken, or a --set that does not apply
    kIoError = 4,       // cannot read the input or write the output
    kInternal = 70,
};

std::optional<xlate5::OrientationMode> parse_mode(const std::string& s) {
    if (s == "G43.4" || s == "angles") return xlate5::OrientationMode::Angles;
    if (s == "G43.5" || s == "vector") return xlate5::OrientationMode::Vector;
    if (s == "G49" || s == "joints") return xlate5::OrientationMode::Joints;
    return std::nullopt;
}

std::map<std::string, double> parse_sets(const std::vector<std::string>& sets) {
    std::map<std::string, double> out;
    for (const auto& s : sets) {
        const auto eq = s.find('=');
        if (eq == std::string::npos || eq == 0) throw CLI::ValidationError("--set", "expected NAME=VALUE, got '" + s + "'");
        char* end = nullptr;
        const std::string value = s.substr(eq + 1);
        const double v = std::strtod(value.c_str(), &end);
        if (value.empty() || *end != '\0' || !std::isfinite(v))
            throw CLI::ValidationError("--set", "'" + value + "' is not a number in '" + s + "'");
        out[s.substr(0, eq)] = v;
    }
    return out;
}

int list_machines() {
    const auto machines = xlate5::bundled_machines();
    if (machines.empty()) {
        std::cerr << "xlate5: no machine files found (searched:";
        for (const auto& d : xlate5::machine_search_path()) std::cerr << " " << d;
        std::cerr << ")\n";
        return kMachineError;
    }
    for (const auto& [name, path] : machines) {
        try {
            const auto m = xlate5::load_machine(path);
            std::printf("%-12s %s\n", name.c_str(), m.description.c_str());
        } catch (const xlate5::MachineError& e) {
            std::printf("%-12s (broken: %s)\n", name.c_str(), e.what());
        }
    }
    return kOk;
}

// Every error ends the same way: its message on standard error and the documented exit code.
int exit_with(std::exception_ptr error) {
    try {
        std::rethrow_exception(error);
    } catch (const xlate5::InputError& e) {
        std::cerr << e.what() << "\n";
        return kInputError;
    } catch (const xlate5::MachineError& e) {
        std::cerr << "xlate5: machine error: " << e.what() << "\n";
        return kMachineError;
    } catch (const xlate5::IoError& e) {
        std::cerr << "xlate5: " << e.what() << "\n";
        return kIoError;
    } catch (const CLI::Error& e) {
        std::cerr << "xlate5: " << e.what() << "\n";
        return kUsage;
    } catch (const std::exception& e) {
        std::cerr << "xlate5: internal error: " << e.what() << "\n";
        return kInternal;
    }
}

// A calibrated copy of the machine file: the new values written in, checked to load, and never
// over the original.
int write_calibrated_copy(const xlate5::Machine& m, const std::string& text, const std::map<std::string, double>& values,
                          const std::string& output) {
    if (std::filesystem::exists(output) && std::filesystem::equivalent(output, m.source_path)) {
        std::cerr << "xlate5: " << output << " is the machine file itself: write the calibrated copy elsewhere\n";
        return kUsage;
    }
    const std::string updated = xlate5::set_parameters(text, m.source_path, values);
    (void)xlate5::load_machine_text(updated, output);
    xlate5::OutputSink sink(output);
    sink.write(updated);
    sink.commit();
    std::printf("wrote %s\n", output.c_str());
    return kOk;
}

// Rows of numbers from a small measurement file: `columns` comma-separated numbers a line,
// '#' comments and blank lines skipped. Prints "path:line:1: ..." and returns false on a bad line.
bool read_rows(const std::string& path, int columns, std::vector<std::vector<double>>& rows, int& exit_code) {
    std::ifstream in(path);
    if (!in) {
        std::cerr << "xlate5: " << path << ": cannot open\n";
        exit_code = kIoError;
        return false;
    }
    std::string l;
    for (int line = 1; std::getline(in, l); ++line) {
        if (auto h = l.find('#'); h != std::string::npos) l.resize(h);
        if (l.find_first_not_of(" \t\r") == std::string::npos) continue;
        std::vector<double> row;
        std::istringstream fields(l);
        std::string field;
        while (std::getline(fields, field, ',')) {
            char* end = nullptr;
            const double v = std::strtod(field.c_str(), &end);
            while (end && (*end == ' ' || *end == '\t' || *end == '\r')) ++end;
            if (end == field.c_str() || (end && *end) || !std::isfinite(v)) break;
            row.push_back(v);
        }
        if (int(row.size()) != columns || std::count(l.begin(), l.end(), ',') != columns - 1) {
            std::cerr << path << ":" << line << ":1: expected " << columns << " comma-separated numbers\n";
            exit_code = kInputError;
            return false;
        }
        rows.push_back(row);
    }
    return true;
}

// xlate5 calibrate fit: least-squares Fourier series through a measured table, printed as a
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
    double residual = 0;
    const auto t = xlate5::fit_fourier(angle, error, order, residual);
    std::printf("# fitted to %zu points of %s: largest residual %.4f mm\n", angle.size(), path.c_str(), residual);
    std::printf("[[compensation]]\njoint = \"%s\"\nby = \"%s\"\nfourier = { a0 = %.6f, cos = [", joint.c_str(), by.c_str(), t.a0);
    for (std::size_t k = 0; k < t.cosines.size(); ++k) std::printf("%s%.6f", k ? ", " : "", t.cosines[k]);
    std::printf("], sin = [");
    for (std::size_t k = 0; k < t.sines.size(); ++k) std::printf("%s%.6f", k ? ", " : "", t.sines[k]);
    std::printf("] }\n");
    return kOk;
}

// xlate5 calibrate plate: a plane through the probed points, and the machine's rho and psi.
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
    const auto fit = xlate5::fit_plate(points);
    std::printf("plate normal (%.6f, %.6f, %.6f) from %zu points, largest residual %.4f mm\n", fit.normal.x(), fit.normal.y(),
                fit.normal.z(), points.size(), fit.residual);
    std::printf("rho = %.6f\npsi = %.6f\n", fit.rho, fit.psi);
    if (output.empty()) return kOk;
    if (machine_name.empty()) {
        std::cerr << "xlate5: calibrate plate -o needs --machine (the file to start from)\n";
        return kUsage;
    }
    try {
        const auto m = xlate5::load_machine(machine_name);
        std::ifstream in(m.source_path, std::ios::binary);
        std::ostringstream text;
        text << in.rdbuf();
        std::printf("was: rho = %.6f, psi = %.6f (%s)\n", m.parameters.count("rho") ? m.parameters.at("rho") : 0.0,
                    m.parameters.count("psi") ? m.parameters.at("psi") : 0.0, m.source_path.c_str());
        return write_calibrated_copy(m, text.str(), {{"rho", fit.rho}, {"psi", fit.psi}}, output);
    } catch (...) {
        return exit_with(std::current_exception());
    }
    return kOk;
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
        const auto m = xlate5::load_machine(machine_name, overrides);
        std::map<std::string, double> set;
        for (const auto& [name, value] : values) {
            const auto it = m.parameters.find(name);
            if (it == m.parameters.end()) {
                std::string known;
                for (const auto& p : m.parameters) known += (known.empty() ? "" : ", ") + p.first;
                throw xlate5::MachineError(m.source_path + ": [parameters] has no '" + name + "' (it has: " + (known.empty() ? "none" : known) + ")");
            }
            std::printf("%s: %.6f -> %.6f\n", name.c_str(), it->second, value);
            set[name] = value;
        }
        if (output.empty()) return kOk;
        std::ifstream in(m.source_path, std::ios::binary);
        std::ostringstream text;
        text << in.rdbuf();
        return write_calibrated_copy(m, text.str(), set, output);
    } catch (...) {
        return exit_with(std::current_exception());
    }
}

}  // namespace

int main(int argc, char** argv) {
    CLI::App app{"xlate5: vendor-neutral 5-axis G-code -> joint-space G-code for a given machine"};
    app.set_version_flag("--version", std::string("xlate5 ") + XLATE5_VERSION);
    app.require_subcommand(0, 1);
    app.fallthrough();  // --machine may come after a subcommand too

    std::string machine_name, input = "-", output = "-", mode_text, preview = "G43.4", extruder = "E", report_path, plot_path, compensation_path;
    std::vector<std::string> sets;
    bool inverse = false, no_segment = false;
    double tolerance = 0, angle_tolerance = 0;
    app.add_option("-m,--machine", machine_name, "bundled machine name (see 'xlate5 machines') or path to a machine .toml");
    app.add_option("-i,--input", input, "input G-code file (default: standard input)");
    app.add_option("-o,--output", output, "output file, written atomically (default: standard output)");
    app.add_option("--set", sets, "override a machine parameter, e.g. --set la=29 (repeatable)");
    app.add_option("--mode", mode_text, "orientation mode at the start of the file: G43.4, G43.5 or G49 (default: the machine's)");
    app.add_option("--extruder-letter", extruder, "input letter that carries extrusion (default E; S3-DeformFDM files use A)");
    app.add_option("--tolerance", tolerance, "largest tip deviation from the programmed line, mm (default: the machine's, 0.01)")
        ->check(CLI::PositiveNumber);
    app.add_option("--angle-tolerance", angle_tolerance, "largest tool-axis deviation, degrees (default: the machine's)")
        ->check(CLI::PositiveNumber);
    app.add_flag("--no-segment", no_segment, "one joint move per input move: no splitting (the tip leaves the line while rotaries turn)");
    app.add_option("--compensation", compensation_path, "measured-error compensation file ([[compensation]] terms), replacing the machine's own");
    app.add_option("--report", report_path, "write the kinematic-error report (JSON) of the translation to this file");
    app.add_option("--plot", plot_path, "write the tip deviation along the file as an SVG plot to this file");
    app.add_flag("--inverse", inverse, "joint-space G-code in, tool-space G-code out (forward kinematics)");
    app.add_option("--preview-form", preview, "with --inverse: write orientation as G43.4 angles or G43.5 I J K")->check(CLI::IsMember({"G43.4", "G43.5"}));
    auto* machines_cmd = app.add_subcommand("machines", "list the bundled machines");
    const auto serve_cmds = xlate5::add_serve_commands(app);
    auto* calibrate_cmd = app.add_subcommand("calibrate", "turn measurements into machine-file values");
    calibrate_cmd->require_subcommand(1);
    auto* fit_cmd = calibrate_cmd->add_subcommand("fit", "fit a Fourier series to a measured error table (CSV: angle,error per line)");
    std::string fit_table, fit_joint = "X", fit_by = "A";
    int fit_order = 1;
    fit_cmd->add_option("table", fit_table, "CSV file: angle (degrees), error (mm) per line; '#' starts a comment")->required();
    fit_cmd->add_option("--order", fit_order, "harmonics (default 1)")->check(CLI::Range(1, 12));
    fit_cmd->add_option("--joint", fit_joint, "joint the error is taken off (for the printed [[compensation]] term)");
    fit_cmd->add_option("--by", fit_by, "rotary joint the error depends on");
    auto* plate_cmd = calibrate_cmd->add_subcommand("plate", "plate tilt rho, psi from probed plate points (CSV: x,y,z per line, 3 or more)");
    std::string plate_points, plate_out;
    plate_cmd->add_option("points", plate_points, "CSV file of probed points, machine frame, mm")->required();
    plate_cmd->add_option("-o,--output", plate_out, "write the machine file with rho and psi set here (never over the original)");
    auto* offset_cmd = calibrate_cmd->add_subcommand("offset", "rotary zero offset from plate touches along Y (CSV: y,z per line; seed 002 eq. 5.5)");
    std::string offset_points, offset_param, offset_out;
    offset_cmd->add_option("points", offset_points, "CSV file of touches: Y, Z (mm), two or more, both sides of the axis")->required();
    offset_cmd->add_option("--param", offset_param, "machine parameter that holds the offset, e.g. a_offset (pentarod)");
    offset_cmd->add_option("-o,--output", offset_out, "write the machine file with the offset set here (never over the original)");
    auto* pivots_cmd = calibrate_cmd->add_subcommand("pivots", "machine parameters (link lengths, pivots) from tips measured at known joints");
    std::string pivots_points, pivots_fit, pivots_out;
    pivots_cmd->add_option("points", pivots_points, "CSV: the joints in the machine file's order, then the measured tip x,y,z (part frame, mm)")->required();
    pivots_cmd->add_option("--fit", pivots_fit, "parameters to fit, comma-separated, e.g. la,lb")->required();
    pivots_cmd->add_option("-o,--output", pivots_out, "write the machine file with the fitted values here (never over the original)");
    auto* centre_cmd = calibrate_cmd->add_subcommand("centre", "rotation centre from dots at several rotary angles (CSV: x,y per line)");
    std::string centre_points, centre_param, centre_out;
    centre_cmd->add_option("points", centre_points, "CSV file of measured dot positions (mm), three or more")->required();
    centre_cmd->add_option("--param", centre_param, "the two machine parameters that hold the centre, X then Y, e.g. cx,cy (pentarod) or wx,wy (koc5)");
    centre_cmd->add_option("-o,--output", centre_out, "write the machine file with the centre set here (never over the original)");

    try {
        app.parse(argc, argv);
    } catch (const CLI::Success& e) {
        return app.exit(e);
    } catch (const CLI::ParseError& e) {
        app.exit(e);
        return kUsage;
    }

    if (machines_cmd->parsed()) return list_machines();
    if (const int code = xlate5::run_serve_commands(*serve_cmds, machine_name); code >= 0) return code;
    if (fit_cmd->parsed()) return calibrate_fit(fit_table, fit_order, fit_joint, fit_by);
    if (plate_cmd->parsed()) return calibrate_plate(plate_points, machine_name, plate_out);
    if (pivots_cmd->parsed()) {
        try {
            if (machine_name.empty()) throw CLI::ValidationError("--machine", "calibrate pivots needs the machine to start from");
            const auto m = xlate5::load_machine(machine_name, parse_sets(sets));
            std::vector<std::vector<double>> rows;
            int code = kOk;
            const int n = int(m.joints.size());
            if (!read_rows(pivots_points, n + 3, rows, code)) return code;
            std::vector<std::string> names;
            std::stringstream list(pivots_fit);
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
            std::ifstream in(m.source_path, std::ios::binary);
            std::ostringstream text;
            text << in.rdbuf();
            const auto fit = xlate5::fit_parameters(text.str(), m.source_path, names, m.parameters, joints, tips);
            for (const auto& name : names)
                std::printf("%s = %.6f   (was %.6f)\n", name.c_str(), fit.values.at(name), m.parameters.at(name));
            std::printf("largest residual %.4f mm over %zu measurements\n", fit.residual, tips.size());
            if (pivots_out.empty()) return kOk;
            std::map<std::string, double> values;
            for (const auto& name : names) values[name] = fit.values.at(name);
            return write_calibrated_copy(m, text.str(), values, pivots_out);
        } catch (...) {
            return exit_with(std::current_exception());
        }
    }
    if (offset_cmd->parsed() || centre_cmd->parsed()) {
        const bool offset = offset_cmd->parsed();
        std::vector<std::vector<double>> rows;
        int code = kOk;
        if (!read_rows(offset ? offset_points : centre_points, 2, rows, code)) return code;
        std::vector<Eigen::Vector2d> pts;
        for (const auto& r : rows) pts.emplace_back(r[0], r[1]);
        if (pts.size() < (offset ? 2u : 3u)) {
            std::cerr << "xlate5: need at least " << (offset ? 2 : 3) << " points, got " << pts.size() << "\n";
            return kInputError;
        }
        std::vector<std::pair<std::string, double>> values;
        if (offset) {
            const auto f = xlate5::fit_rotary_offset(pts);
            std::printf("rotary offset %.6f deg (atan of dZ/dY over %zu touches), plate Z at Y = 0: %.4f mm, largest residual %.4f mm\n",
                        f.offset_deg, pts.size(), f.z_error, f.residual);
            if (!offset_param.empty()) values = {{offset_param, f.offset_deg}};
        } else {
            const auto f = xlate5::fit_circle(pts);
            std::printf("rotation centre (%.4f, %.4f), radius %.4f mm, largest residual %.4f mm over %zu dots\n", f.centre.x(),
                        f.centre.y(), f.radius, f.residual, pts.size());
            if (!centre_param.empty()) {
                std::vector<std::string> names;
                std::stringstream list(centre_param);
                for (std::string name; std::getline(list, name, ',');) names.push_back(name);
                if (names.size() != 2 || names[0].empty() || names[1].empty() || names[0] == names[1])
                    return exit_with(std::make_exception_ptr(CLI::ValidationError("--param", "expected two parameter names, X,Y (e.g. cx,cy), got '" + centre_param + "'")));
                values = {{names[0], f.centre.x()}, {names[1], f.centre.y()}};
            }
        }
        try {
            return store_calibration(offset ? "offset" : "centre", machine_name, values, offset ? offset_out : centre_out, parse_sets(sets));
        } catch (...) {
            return exit_with(std::current_exception());
        }
    }

    std::map<std::string, double> overrides;
    xlate5::TranslatorOptions options;
    try {
        if (machine_name.empty()) throw CLI::ValidationError("--machine", "is required (see 'xlate5 machines')");
        overrides = parse_sets(sets);
        if (!mode_text.empty()) {
            options.start_mode = parse_mode(mode_text);
            if (!options.start_mode) throw CLI::ValidationError("--mode", "expected G43.4, G43.5 or G49");
        }
        if (extruder.size() != 1 || !std::isalpha(static_cast<unsigned char>(extruder[0])))
            throw CLI::ValidationError("--extruder-letter", "expected one letter");
        options.extruder_letter = char(std::toupper(static_cast<unsigned char>(extruder[0])));
    } catch (...) {
        return exit_with(std::current_exception());
    }
    options.inverse = inverse;
    options.preview_form = preview == "G43.5" ? xlate5::OrientationMode::Vector : xlate5::OrientationMode::Angles;
    options.input_name = input == "-" ? "<stdin>" : input;

    std::optional<xlate5::Machine> machine;
    try {
        machine = xlate5::load_machine(machine_name, overrides);
        if (tolerance > 0) machine->motion.tolerance = tolerance;
        if (angle_tolerance > 0) machine->motion.angle_tolerance = angle_tolerance;
        if (no_segment) machine->motion.segment = false;
        if (!compensation_path.empty()) xlate5::load_compensation_file(compensation_path, *machine);
    } catch (...) {
        return exit_with(std::current_exception());
    }

    int in_fd = 0;
    try {
        const xlate5::Kinematics kinematics(*machine);  // a layout outside the family: MachineError
        if (input != "-") {
            in_fd = ::open(input.c_str(), O_RDONLY | O_CLOEXEC);
            if (in_fd < 0) throw xlate5::IoError(input + ": cannot open: " + std::strerror(errno));
        }
        std::optional<xlate5::DeviationReport> report;
        if (!report_path.empty() || !plot_path.empty()) {
            report.emplace(options.input_name, machine->name, machine->motion.tolerance, machine->motion.angle_tolerance);
            options.report = &*report;
        }
        xlate5::Translator translator(kinematics, options);
        xlate5::LineReader reader(in_fd, options.input_name);
        xlate5::OutputSink sink(output);
        const auto stats = xlate5::translate_stream(reader, translator, sink);
        // The report files are written like the output: whole, or not at all.
        std::optional<xlate5::OutputSink> report_sink, plot_sink;
        if (report) {
            report->set_lines(stats.lines_in, stats.lines_out);
            if (!report_path.empty()) report_sink.emplace(report_path), report_sink->write(report->json());
            if (!plot_path.empty()) plot_sink.emplace(plot_path), plot_sink->write(report->svg());
        }
        sink.commit();
        if (report_sink) report_sink->commit();
        if (plot_sink) plot_sink->commit();
    } catch (...) {
        return exit_with(std::current_exception());
    }
    if (in_fd > 0) ::close(in_fd);
    return kOk;
}
