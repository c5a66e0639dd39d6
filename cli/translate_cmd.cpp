// SPDX-License-Identifier: GPL-3.0-or-later
// `xlate5 --machine M ...`: loads the machine and runs the translation stages over a stream
// (stage: command line; the stages themselves live in translators/).
#include "cli/translate_cmd.hpp"

#include <cctype>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <fcntl.h>
#include <iostream>
#include <map>
#include <optional>
#include <sys/stat.h>
#include <unistd.h>

#include "cli/options.hpp"
#include "translators/inspect/preflight.hpp"
#include "translators/inspect/preview.hpp"
#include "translators/inspect/slicer_times.hpp"
#include "cli/progress.hpp"
#include "cli/provenance.hpp"
#include "translators/pipeline/compensation.hpp"
#include "translators/error.hpp"
#include "translators/machine/firmware_config.hpp"
#include "translators/inputs/input_front.hpp"
#include "translators/pipeline/keep_out.hpp"
#include "translators/kinematics/kinematics.hpp"
#include "translators/machine/machine.hpp"
#include "translators/inspect/report.hpp"
#include "translators/pipeline/stream.hpp"
#include "translators/pipeline/translator.hpp"

#ifndef XLATE5_VERSION
#define XLATE5_VERSION "0.0.0"
#endif

namespace xlate5::cli {
namespace {

// An error in made input, told at the file and line it comes from.
InputError traced(const InputError& e, const MadeInput& made) {
    if (e.line() == 0 || e.line() > made.origin.size()) return e;
    const SourceLine& at = made.origin[e.line() - 1];
    return InputError(at.file, at.line, at.inserted ? 1 : e.column(),
                      at.inserted ? "in the change join writes before this line: " + e.message() : e.message());
}

std::optional<OrientationMode> parse_mode(const std::string& s) {
    if (s == "G43.4" || s == "angles") return OrientationMode::Angles;
    if (s == "G43.5" || s == "vector") return OrientationMode::Vector;
    if (s == "G49" || s == "joints") return OrientationMode::Joints;
    return std::nullopt;
}

}  // namespace

void add_translate_options(CLI::App& app, TranslateOptions& o) {
    app.add_option("-i,--input", o.input, with_default("input G-code file", "standard input"))->option_text("FILE");
    app.add_option("-o,--output", o.output, with_default("output file, written atomically", "standard output"))->option_text("FILE");
    app.add_option("--mode", o.mode, with_default("orientation mode at the start of the file", "the machine file's [input] mode"))
        ->option_text("G43.4|G43.5|G49");
    app.add_option("--extruder-letter", o.extruder, with_default("input letter that carries extrusion (S3-DeformFDM files use A)", "E"))
        ->option_text("LETTER");
    app.add_option("--tolerance", o.tolerance, with_default("largest tip deviation from the programmed line, above 0 and at most 10 mm",
                                                            "the machine file's [motion] tolerance, else " +
                                                                number_text(MotionSettings{}.tolerance)))
        ->check(number_in(0, 10, "mm", true))
        ->option_text("MM");
    app.add_option("--angle-tolerance", o.angle_tolerance,
                   with_default("largest tool-axis deviation, above 0 and at most 90 degrees",
                                "the machine file's [motion] angle_tolerance, else " + number_text(MotionSettings{}.angle_tolerance)))
        ->check(number_in(0, 90, "degrees", true))
        ->option_text("DEG");
    app.add_flag("--no-segment", o.no_segment, "one joint move per input move: no splitting (the tip leaves the line while rotaries turn)");
    app.add_option("--compensation", o.compensation,
                   with_default("measured-error compensation file ([[compensation]] terms), replacing the machine's own", "the machine's own"))
        ->option_text("FILE");
    app.add_option("--report", o.report, "write the kinematic-error report (JSON) of the translation to this file")->option_text("FILE");
    app.add_option("--plot", o.plot, "write the tip deviation along the file as an SVG plot to this file")->option_text("FILE");
    app.add_flag("--compact-words", o.compact_words, "the input is written without blanks: X1.5E-05 is X1.5 and E-05 (as the line '; xlate5: compact-words')");
    app.add_option("--preview", o.preview_html,
                   "write a page to look at before printing: the tip path in 3D coloured by tilt or deviation, the tool axis, the pole crossings, unwinds, branch changes and re-zeros --report counts marked, each joint against its limits")
        ->option_text("FILE.html");
    app.add_option("--baud", o.baud,
                   with_default("the serial link's speed for the pre-flight estimate (--report's \"preflight\", and its summary on a terminal): "
                                "bits/s, 10 bits a byte, lines framed with numbers and checksums", "115200"))
        ->check(number_in(300, 1e8, "bits/s", false))
        ->option_text("BITS");
    app.add_flag("--keep-slicer-times", o.keep_slicer_times,
                 "leave the slicer's M73 P/R Q/S, ;TIME:, ;TIME_ELAPSED: and '; estimated printing time' as it wrote them; "
                 "without it, an output file (-o FILE, or FILE in place) has them rewritten from xlate5's own estimate of "
                 "what it wrote (docs/preflight.md); standard output, a pipe or a device keeps them as written (a stream "
                 "cannot know its total before its end)");
    app.add_flag("--no-progress", o.no_progress, "no progress bar on standard error (there is one only when it is a terminal)");
    app.add_option("file", o.file,
                   "translate FILE in place, atomically (as a slicer's post-processing script: PrusaSlicer, OrcaSlicer, SuperSlicer "
                   "call SCRIPT FILE)")
        ->option_text("FILE");
    app.add_flag("--force", o.force,
                 "translate a file that starts with xlate5's header of the space it would write (already translated: "
                 "refused without it)");
    app.add_flag("--inverse", o.inverse, "joint-space G-code in, tool-space G-code out (forward kinematics)");
    app.add_option("--from", o.from,
                   "the input is joint-space G-code written for machine NAME|PATH: its forward kinematics give the tip and "
                   "tool axis, translated for --machine (retargeting)")
        ->option_text("MACHINE");
    app.add_option("--place", o.place,
                   with_default("with --from: where the source's part frame lies on this machine, X,Y,Z in mm (added to every "
                                "tip: the part placed elsewhere on this bed than on the source's)", "0,0,0"))
        ->delimiter(',')
        ->expected(3)
        ->check(number_in(-1e6, 1e6, "mm", false))
        ->option_text("X,Y,Z");
    app.add_option("--preview-form", o.preview, with_default("with --inverse: write orientation as G43.4 angles or G43.5 I J K", "G43.4"))
        ->check(CLI::IsMember({"G43.4", "G43.5"}))
        ->option_text("G43.4|G43.5");
    app.add_option("--input-format", o.input_format, with_default("gcode, apt (APT / NX CLSF) or waypoints (x y z nx ny nz)", "auto: CL data or G-code, by content"))
        ->check(CLI::IsMember({"auto", "gcode", "apt", "waypoints"}));
    app.add_option("--extrusion-per-mm", o.extrusion_per_mm, with_default("apt and waypoints: E (mm of filament) per mm of tip path on printing moves", "0"))
        ->check(number_in(0, 100, "mm of filament per mm", false));
    app.add_option("--waypoint-feed", o.waypoint_feed, with_default("waypoints: feed of the printing moves, mm/min", "1200"))
        ->check(number_in(1, 1e6, "mm/min", false));
    app.add_option("--collision", o.collision,
                   with_default("a machine with [[bodies]]: a move whose tool bodies meet the printed part, the bed or a body is "
                                "refused (exit 1), warned of on stderr and written, or not checked",
                                "refuse"))
        ->check(CLI::IsMember({"refuse", "warn", "off"}))
        ->option_text("refuse|warn|off");
    app.add_option("--reroute", o.reroute,
                   with_default("a travel (no E) whose tool bodies would meet something is lifted along the tool axis, "
                                "carried across and lowered, instead of refused",
                                "the machine file's [collision] reroute, else on"))
        ->check(CLI::IsMember({"on", "off"}))
        ->option_text("on|off");
    app.add_option("--lift", o.lift, with_default("the re-routed travel's lift along the tool axis, mm (then twice, four times)",
                                                  "the machine file's [collision] lift, else 10"))
        ->check(number_in(0.1, 500, "mm", false));
    app.add_option("--keep-out", o.keep_out, "ITEMS.csv (x, y, height per line): R of a nozzle turning about its own axis (addin4) "
                                            "is set normal to the path, toward the nearest item at or below the current Z");
}

int run_translate(const Common& common, const TranslateOptions& given, const MadeInput* made) {
    std::map<std::string, double> overrides;
    TranslatorOptions options;
    TranslateOptions o = given;
    try {
        if (!o.file.empty()) {
            if (o.input != "-" || o.output != "-")
                throw CLI::ValidationError("FILE", "is translated in place: give FILE, or -i and -o, not both");
            o.input = o.output = o.file;
        }
        if (common.machine.empty()) throw CLI::ValidationError("--machine", "is required (see 'xlate5 machines')");
        overrides = parse_sets(common.sets);
        if (!o.mode.empty()) {
            options.start_mode = parse_mode(o.mode);
            if (!options.start_mode) throw CLI::ValidationError("--mode", "expected G43.4, G43.5 or G49");
        }
        if (o.extruder.size() != 1 || !std::isalpha(static_cast<unsigned char>(o.extruder[0])))
            throw CLI::ValidationError("--extruder-letter", "expected one letter");
        options.extruder_letter = char(std::toupper(static_cast<unsigned char>(o.extruder[0])));
        options.notice = [](const std::string& m) { std::cerr << printable(m) << "\n"; };
        if (o.input_format == "gcode" && o.extrusion_per_mm > 0)
            throw CLI::ValidationError("--extrusion-per-mm", "is for apt and waypoints input (G-code has its own E)");
        if (o.inverse && o.input_format != "auto" && o.input_format != "gcode")
            throw CLI::ValidationError("--input-format", "--inverse reads joint-space G-code only");
        if (!o.place.empty() && o.from.empty())
            throw CLI::ValidationError("--place", "places a retargeted part (--from); a tool-space file is placed in its slicer");
        if (!o.from.empty()) {
            if (o.inverse) throw CLI::ValidationError("--from", "reads joint space and writes joint space (not with --inverse)");
            if (o.place.size() == 3) std::copy(o.place.begin(), o.place.end(), options.place.begin());
            if (!o.mode.empty()) throw CLI::ValidationError("--mode", "is not for --from: its input is joints, read through its machine's kinematics");
            if (o.input_format != "auto" && o.input_format != "gcode")
                throw CLI::ValidationError("--input-format", "--from reads joint-space G-code only");
        }
    } catch (...) {
        return exit_with(std::current_exception());
    }
    options.inverse = o.inverse;
    options.preview_form = o.preview == "G43.5" ? OrientationMode::Vector : OrientationMode::Angles;
    options.input_name = o.input == "-" ? "<stdin>" : o.input;
    // A slicer's post-processing works on a temporary copy; the name the user will see is this.
    if (const char* final_name = std::getenv("SLIC3R_PP_OUTPUT_NAME"); !o.file.empty() && final_name && *final_name)
        options.input_name = final_name;
    if (made) options.input_name = "<join>";

    std::optional<Machine> machine, from_machine;
    try {
        if (!o.from.empty()) from_machine = load_machine(o.from);
        machine = load_machine(common.machine, overrides);
        if (o.tolerance > 0) machine->motion.tolerance = o.tolerance;
        if (o.angle_tolerance > 0) machine->motion.angle_tolerance = o.angle_tolerance;
        if (o.no_segment) machine->motion.segment = false;
        if (!o.compensation.empty()) load_compensation_file(o.compensation, *machine);
    } catch (...) {
        return exit_with(std::current_exception());
    }

    int in_fd = 0;
    try {
        const Kinematics kinematics(*machine);  // a layout outside the family: MachineError
        std::optional<Kinematics> from_kinematics;
        if (from_machine) from_kinematics.emplace(*from_machine), options.from = &*from_kinematics;
        if (made) {
            in_fd = made->fd;
        } else if (o.input != "-") {
            in_fd = ::open(o.input.c_str(), O_RDONLY | O_CLOEXEC);
            if (in_fd < 0) throw IoError(o.input + ": cannot open: " + std::strerror(errno));
        }
        std::optional<KeepOutItems> keep_out;
        if (!o.keep_out.empty()) {
            if (o.inverse) throw CLI::ValidationError("--keep-out", "translates tool space to joints (not with --inverse)");
            keep_out = load_keep_out(o.keep_out);
            options.keep_out = &*keep_out;
        }
        std::optional<DeviationReport> report;
        if (!o.report.empty() || !o.plot.empty() || !o.preview_html.empty()) {  // the preview marks the report's events
            report.emplace(options.input_name, machine->name, machine->motion.tolerance, machine->motion.angle_tolerance);
            options.report = &*report;
        }
        options.compact_words = o.compact_words;
        options.collision = o.collision == "off" ? CollisionPolicy::Off : o.collision == "warn" ? CollisionPolicy::Warn : CollisionPolicy::Refuse;
        if (!o.reroute.empty()) options.reroute = o.reroute == "on";
        if (o.lift > 0) options.lift = o.lift;
        if (machine->geometry && options.collision != CollisionPolicy::Off) {
            if (report) report->collisions.set_checked();
            const bool warn = options.collision == CollisionPolicy::Warn;
            const std::string name = options.input_name;
            options.on_collision = [&report, warn, name](const CollisionEvent& ev) {
                if (report) {
                    DeviationReport::CollisionMark mark{ev.line, ev.moves_written, ev.bead_line, ev.tool_body, ev.other, {ev.at.x(), ev.at.y(), ev.at.z()}};
                    if (ev.rerouted) report->collisions.add_reroute(ev.line, ev.message(), std::move(mark));
                    else report->collisions.add_collision(ev.line, ev.message(), std::move(mark));
                }
                if (warn) std::cerr << printable(name) << ":" << ev.line << ": warning: " << printable(ev.message()) << "\n";
            };
        }
        Translator translator(kinematics, options);
        FrontOptions front_options;
        front_options.format = o.inverse || from_machine ? InputFormat::GCode : *parse_input_format(o.input_format);
        front_options.input_name = options.input_name;
        front_options.extrusion_per_mm = o.extrusion_per_mm;
        front_options.waypoint_feed = o.waypoint_feed;
        front_options.chord_tolerance = 0.5 * machine->motion.tolerance;  // the other half for the split
        front_options.extrusion_decimals = machine->dialect.extrusion_decimals;
        InputFront front(translator, front_options);
        LineReader reader(in_fd, options.input_name);
        OutputSink sink(o.output);
        // A pipe or a terminal in: write what is decided before waiting for more (a filter).
        // A regular file in: a progress bar on a terminal, sized by the file.
        struct stat in_stat{};
        const bool regular = ::fstat(in_fd, &in_stat) == 0 && S_ISREG(in_stat.st_mode);
        Progress progress(regular ? std::uint64_t(in_stat.st_size) : 0, !o.no_progress && ::isatty(2));
        std::optional<xlate5::Preview> preview;
        // The report's counts of the written lines come from the preview's scan of them.
        if (!o.preview_html.empty() || (!o.report.empty() && !o.inverse)) preview.emplace(kinematics, *report);
        // The pre-flight estimate of the written joints: for the report, and said on a terminal.
        const bool terminal_summary = !o.inverse && ::isatty(2) && !o.output.empty() && o.output != "-";
        std::optional<Preflight> preflight;
        if (!o.inverse && (!o.report.empty() || !o.preview_html.empty() || terminal_summary)) preflight.emplace(*machine, o.baud);
        // The slicer's time lines are rewritten in an output file (its total is known at the end:
        // a stream keeps them as written); the file is read back only when a block held one.
        const bool retime = !o.inverse && !o.keep_slicer_times && !sink.temporary().empty();
        bool times_seen = false;

        // The first line says what the file is: binary G-code is refused, xlate5's own header
        // of the space this run writes is a second translation (refused unless forced), the
        // header of the other space (a preview read back) is dropped: the output has its own.
        const Space writes = o.inverse ? Space::Tool : Space::Joint;
        // Klipper's dialect: the extra axes are registered before anything uses their letters.
        const std::string head = provenance_header(XLATE5_VERSION, machine->name, writes) + "\n" +
                                 (writes == Space::Joint ? firmware_preamble(*machine) : std::string());
        const auto first_line = [&](std::string_view first, std::string& out) {
            if (is_binary_gcode(first)) throw InputError(options.input_name, 1, 1, binary_gcode_message());
            const std::optional<Space> was = read_provenance(first);
            // Retargeting reads joint space: another translation's output is its input.
            if (from_machine && was == Space::Tool)
                throw InputError(options.input_name, 1, 1, "this file is xlate5's tool-space output; --from reads joint-space G-code");
            if (from_machine && was == Space::Joint) {
                out += head;
                return false;
            }
            if (was == writes && !o.force)
                throw InputError(options.input_name, 1, 1,
                                 std::string("this file is xlate5's output already (") +
                                     (writes == Space::Joint ? "joint space: translating it again would move the print by the kinematics twice"
                                                             : "tool space: --inverse reads joint space") +
                                     "); give --force to translate it anyway");
            out += head;
            return !was || was == writes;
        };
        const auto stats = translate_stream(
            reader, front, sink, !regular, [&](const StreamStats& s) { progress.update(s.bytes_in, s.lines_in); },
            preview || preflight || retime ? std::function<void(std::string_view)>([&](std::string_view block) {
                if (preview) preview->scan(block);
                if (preflight) preflight->scan(block);
                if (retime && !times_seen) times_seen = may_hold_slicer_times(block);
            })
                                 : std::function<void(std::string_view)>(),
            first_line);
        if (stats.lines_in == 0) {
            sink.write(head);  // an empty input: the header alone, and said (a slicer's failed export, a wrong path)
            if (preview) preview->scan(head);
            if (preflight) preflight->scan(head);
            std::cerr << printable(options.input_name) << ": note: the input is empty: the output holds only xlate5's header\n";
        }
        // The report files are written like the output: whole, or not at all.
        std::optional<OutputSink> report_sink, plot_sink, preview_sink;
        if (preflight) {
            preflight->finish();
            std::vector<std::pair<std::uint64_t, std::uint64_t>> drains;
            for (const auto& r : preflight->drains()) drains.emplace_back(r.first, r.last);
            if (preview) preview->set_drains(std::move(drains));
        }
        if (!o.preview_html.empty()) preview_sink.emplace(o.preview_html), preview_sink->write(preview->html(options.input_name + " on " + machine->name));
        if (preview && !o.inverse) report->set_written(preview->report_json() + (preflight ? "  \"preflight\": " + preflight->json() + ",\n" : ""));
        if (report) {
            report->set_lines(stats.lines_in, stats.lines_out + (stats.lines_in == 0 ? 1 : 0));
            if (!o.report.empty()) report_sink.emplace(o.report), report_sink->write(report->json());
            if (!o.plot.empty()) plot_sink.emplace(o.plot), plot_sink->write(report->svg());
        }
        // The output with the slicer's time lines from the estimate: a second temporary file,
        // renamed into place instead of the first (which its sink removes).
        std::optional<OutputSink> retimed;
        if (retime && times_seen) retimed.emplace(o.output), retime_file(*machine, o.baud, sink.temporary(), *retimed);
        (retimed ? *retimed : sink).commit();
        if (report_sink) report_sink->commit();
        if (plot_sink) plot_sink->commit();
        if (preview_sink) preview_sink->commit();
        if (preflight && terminal_summary) std::cerr << preflight->summary();
    } catch (const InputError& e) {
        return exit_with(std::make_exception_ptr(made ? traced(e, *made) : e));
    } catch (...) {
        return exit_with(std::current_exception());
    }
    if (in_fd > 0 && !made) ::close(in_fd);
    return kOk;
}

}  // namespace xlate5::cli
