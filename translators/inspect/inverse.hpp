// SPDX-License-Identifier: GPL-3.0-or-later
// The inverse direction, its own small pipeline: the firmware's joint-space G-code (its axis
// letters) -> the lexer -> line_commands -> measured errors added back -> forward kinematics ->
// the tool emitter (G43.4 angles or G43.5 vector). For previews and round-trip checks:
// translate(inverse(x)) gives x back. Lines it does not need to understand pass through.
// May call: the lexer, line_commands, the compensation tables (undo), kinematics (forward only),
// joint_limits (to refuse joints the machine cannot be at), the tool emitter.
#pragma once
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "translators/inputs/gcode_lexer.hpp"
#include "translators/kinematics/kinematics.hpp"
#include "translators/pipeline/line_commands.hpp"
#include "translators/machine/machine.hpp"
#include "translators/pipeline/modes.hpp"
#include "translators/inspect/tool_emitter.hpp"
#include "translators/pipeline/travel_clamp.hpp"

namespace xlate5 {

// The words of a joint-space line read as the firmware reads them (its joint letters, the
// numbers), and the place an error names (file, line, column): the inverse's reading, apart
// from what it does with the words.
class JointWords {
public:
    JointWords(const Machine& machine, std::string input_name) : machine_(machine), input_name_(std::move(input_name)) {}
    void at_line(std::uint64_t line_no) { line_no_ = line_no; }
    std::uint64_t line() const { return line_no_; }
    const std::string& input_name() const { return input_name_; }
    [[noreturn]] void fail(std::uint32_t column, const std::string& message) const;
    double number(const Param& p) const;
    PassedNumber passed(const Param& p, bool inches) const;
    int joint_of(char letter) const;  // the joint the firmware knows by this letter, or -1

private:
    const Machine& machine_;
    std::string input_name_;
    std::uint64_t line_no_ = 0;
};

class InverseTranslator {
public:
    InverseTranslator(const Kinematics& kinematics, std::string input_name, char extruder_letter, OrientationMode preview_form);

    // Translates one line (without '\n'), appending its output to `out`. Throws InputError naming
    // the file, line and column; the state is then as before the line.
    void feed(std::string_view line, std::uint64_t line_no, std::string& out);
    // The input is compact from its first line, as if it began with the compact declaration (gcode_lexer.hpp).
    void set_compact_words() { block_.compact_words = true; }
    // The output goes on to another machine's translation (--from): its rotary re-zeros
    // (G92 C0) change no pose and are left out, its G28, whatever joints it names, is a bare G28
    // (the printer that runs the file homes as it homes), and each move is placed on that
    // machine by `clamp` (travel moves past its linear travel held at the limits).
    void set_retarget(TravelClamp& clamp) { retarget_ = &clamp; }

    const std::vector<double>& joints() const { return state_.q; }  // nominal: measured errors added back
    const Pose& pose() const { return state_.pose; }
    const Modes& modes() const { return state_.modes; }

private:
    // What a line can change, rolled back as one when it fails. (sent_q_, what the firmware was
    // told, is not: the firmware heard the line whatever came of its translation.)
    struct State {
        std::vector<double> q;
        Pose pose;
        Modes modes;
    };
    [[noreturn]] void fail(std::uint32_t column, const std::string& message) const { words_.fail(column, message); }
    void apply_modal(int code10, std::uint32_t column, Params words, std::string& out);
    void run_command(const CommandWord& c, std::string_view body, bool alone, Params words, std::string& out);
    void move(int gcode, Params words, std::string& out);
    void set_position(Params words, std::string_view body, std::string& out);
    // A retargeted move cut into n parts along the source's path (move): the first n - 1, and
    // the last part's E and each part's F.
    void source_parts(int gcode, int n, bool travel, const std::optional<PassedNumber>& e, const std::optional<PassedNumber>& f,
                      std::string& out);
    void home(Params words, std::string& out);

    const Kinematics& kin_;
    const Machine& machine_;
    JointWords words_;
    char extruder_letter_;
    ToolEmitter emitter_;
    State state_, saved_;
    std::vector<double> sent_q_;  // the joints as the firmware was told them (compensated)
    std::vector<double> q_next_;
    Block block_;
    LineCommands commands_;
    LinePlan plan_;
    std::string move_letters_, position_letters_;  // see plan_line
    TravelClamp* retarget_ = nullptr;
    std::vector<double> part_q_;  // scratch of source_parts
};

}  // namespace xlate5
