// SPDX-License-Identifier: GPL-3.0-or-later
// Fuzz target: G-code text through the whole translation, for every bundled machine and every
// input mode: lexer -> interpreter -> planner -> motion -> compensation -> emitter under the
// look-back (G43.4, G43.5 or G49 to start with), or the inverse pipeline (joint-space G-code ->
// G43.4 or G43.5 preview). Stage: test harness; may call the front door (translator.hpp).
//
// Input: byte 0 picks the machine, byte 1 the configuration (bits 0-2: the mode, 5 choices;
// bit 3: look-back on; bit 4: deviation report; bit 5: compact words; bits 6-7: the input's
// format: 0 or 1 G-code straight in, 2 APT / NX CLSF records, 3 a waypoint table, both through the
// input front as `--input-format` reads them), the rest is the input.
// Refused lines (InputError) are part of the game: the translator promises its state is
// unchanged by them, so the lines after are fed too. Anything else thrown is a finding.
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "fuzz/fuzz_common.hpp"
#include "translators/error.hpp"
#include "translators/inputs/gcode_lexer.hpp"
#include "translators/inputs/input_front.hpp"
#include "translators/kinematics/kinematics.hpp"
#include "translators/inspect/report.hpp"
#include "translators/pipeline/translator.hpp"

using namespace xlate5;

namespace {

// Machines and their kinematics are built once per process; a translator over them is cheap to
// build (about 0.3 ms under the sanitizers), so each input starts from a fresh one, in the state
// a file starts in. The cost of an input is its moves: split to the machine's tolerance (0.01 mm)
// one tilted move is thousands of pieces. The fuzzed machines are split coarser (kTolerance,
// kAngleTolerance): the same code runs, with fewer turns of the same loops. A coarse tolerance
// does not bound a long turn (C-338988 is 7,500 pieces at 45 degrees: 3 s under the sanitizers),
// so the pieces per input line are capped lower too (kMaxPieces): the refusal past the cap is
// still reached, after a few pieces instead of thousands.
constexpr double kTolerance = 10, kAngleTolerance = 45;
constexpr int kMaxPieces = 8;
// The look-back translates its held lines again for each end it tries at a travel move, for
// every line that passes a limit: with the default window (2000 lines) and 64 ends an input of a
// few hundred bytes is all held, and retranslated up to 64 times a line. A window of one line and
// two ends run the same code (an unwinding that works, one that does not, no solution left), and
// also reach the window's overflow, which no short input reaches with the default.
constexpr std::size_t kLookback = 1;
constexpr int kCandidates = 2;

const std::vector<std::unique_ptr<Kinematics>>& kinematics() {
    static const auto all = [] {
        std::vector<std::unique_ptr<Kinematics>> k;
        for (Machine m : fuzz::bundled()) {
            m.motion.tolerance = kTolerance;
            m.motion.angle_tolerance = kAngleTolerance;
            m.motion.max_pieces = kMaxPieces;
            k.push_back(std::make_unique<Kinematics>(m));
        }
        return k;
    }();
    return all;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    if (size < 2) return 0;
    const auto& kins = kinematics();
    const Kinematics& kin = *kins[data[0] % kins.size()];
    const unsigned config = data[1];
    const std::string_view text(reinterpret_cast<const char*>(data + 2), size - 2);

    TranslatorOptions options;
    options.input_name = "fuzz.gcode";
    std::optional<DeviationReport> report;
    const unsigned format = (config >> 6) & 3u;
    switch ((config & 7u) % 5u) {
    case 0: options.start_mode = OrientationMode::Angles; break;
    case 1: options.start_mode = OrientationMode::Vector; break;
    case 2: options.start_mode = OrientationMode::Joints; break;
    case 3: options.inverse = true; options.preview_form = OrientationMode::Angles; break;
    default: options.inverse = true; options.preview_form = OrientationMode::Vector; break;
    }
    if (config & 16u) {
        report.emplace(options.input_name, kin.machine().name, kin.machine().motion.tolerance, kin.machine().motion.angle_tolerance);
        options.report = &*report;
    }
    Translator translator(kin, options);
    if (config & 8u) translator.set_lookback(kLookback, kCandidates);
    std::string out;
    if (config & 32u) translator.feed("; " + std::string(kCompactDeclaration), 0, out);

    // CL data and waypoint tables go through the input front (records to canonical G-code), with
    // CL arcs chorded coarser than the command line's 0.005 mm: the same code, fewer chords.
    std::optional<InputFront> front;
    if (format >= 2 && !options.inverse)
        front.emplace(translator, FrontOptions{format == 2 ? InputFormat::Apt : InputFormat::Waypoints, options.input_name, 0.05, 1200, 1.0});
    std::uint64_t line_no = 0;
    for (std::size_t pos = 0; pos <= text.size();) {
        std::size_t end = text.find('\n', pos);
        if (end == std::string_view::npos) end = text.size();
        try {
            if (front) front->feed(text.substr(pos, end - pos), ++line_no, out);
            else translator.feed(text.substr(pos, end - pos), ++line_no, out);
        } catch (const InputError&) {
        }
        if (out.size() > (1u << 16)) out.clear();  // the output is not checked here, only produced
        pos = end + 1;
    }
    try {
        if (front) front->finish(line_no, out);
        else translator.finish(out);
    } catch (const InputError&) {
    }
    if (report) {
        report->set_lines(line_no, 0);
        (void)report->json();
        (void)report->svg();
    }
    return 0;
}
