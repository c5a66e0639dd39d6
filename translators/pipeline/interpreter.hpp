// SPDX-License-Identifier: GPL-3.0-or-later
// The interpreter stage, between the lexer and the planner: one line's words + the modal state
// (G43.4/G43.5/G49, G90/G91, G20/G21, G17-G19, G93/G94, M82/M83, F, the tilted work plane of
// G68.2/G53.1/G69) -> the line's commands, as values (commands.hpp): a ToolMove (G0/G1 under
// tool-centre-point control, G53.1), an Arc (G2/G3), a JointMove (G49), a position set (G92),
// homing (G28), or text passed on as written. What a move leaves out is "as before", for the
// planner to fill in: the interpreter keeps its modal state and reads no other stage's.
// May call: the lexer, line_commands, work_plane (the plane's frame), arcs (an arc's plane).
#pragma once
#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include <Eigen/Core>

#include "translators/inputs/gcode_lexer.hpp"
#include "translators/machine/machine.hpp"
#include "translators/pipeline/commands.hpp"
#include "translators/pipeline/line_commands.hpp"
#include "translators/pipeline/modes.hpp"
#include "translators/pipeline/work_plane.hpp"

namespace xlate5 {

// The interpreter's own state.
struct ModalState {
    OrientationMode mode = OrientationMode::Angles;
    Modes modes;
    StampedPlane plane;  // G68.2 ... G69: X Y Z are read in the plane's frame (work_plane.hpp)
};

// The letters that name an axis in a command's words on `machine`: X Y Z, the arc's I J K and
// the machine's joints. The service reads G28's words with it too (homes_all).
bool is_axis_letter(const Machine& machine, char letter);

// A line read into its steps (line_commands.hpp), and the letters reading it needs.
struct LineSteps {
    Block block;
    LineCommands commands;
    LinePlan plan;
    std::string move_letters, position_letters;  // see plan_line
};

// The joints a machine's letters name, as tables made once (not a search of the joints per
// word), and its joints as bits.
struct JointLetters {
    explicit JointLetters(const Machine& machine);
    // The joint a word's letter names, -1 for none. (A word's letter is upper case A to Z, and no
    // joint is named otherwise.)
    int joint_of(char letter) const {
        const auto k = std::size_t(letter - 'A');
        return k < joint.size() ? joint[k] : -1;
    }
    // The rotary joint a word's letter names, -1 for none (a linear joint's letter, none, or a
    // letter a tool move reads as something else: X Y Z I J K E F).
    int rotary_of(char letter) const {
        const auto k = std::size_t(letter - 'A');
        return k < rotary.size() ? rotary[k] : -1;
    }
    std::array<int, 26> joint, rotary;
    cmd::JointBits linear_joints = 0, rotary_joints = 0;  // one bit a joint
};

class Interpreter {
public:
    Interpreter(const Machine& machine, ModalState& state, std::string input_name, char extruder_letter);

    // One line (without '\n') as commands into `out` (cleared first), in order of execution; the
    // modal state changed by it. Throws InputError naming the file, line and column when the
    // line cannot be read (nothing has changed then), LineError(column, cause) when it cannot be
    // interpreted (the modal state is then the caller's to restore). `nul_after`: a NUL follows
    // the line (lex_line reads it in place).
    void interpret(std::string_view line, std::uint64_t line_no, cmd::CommandList& out, bool nul_after = false);
    // The input is compact from its first line, as if it began with the compact declaration (gcode_lexer.hpp).
    void set_compact_words() { steps_.block.compact_words = true; }
    // The line read last takes its text whole (a display or file command: fit_marlin_lines).
    bool text_argument() const { return steps_.block.text_argument; }

private:
    void read(std::string_view line, std::uint64_t line_no, bool nul_after);  // the words and steps: throws InputError
    PassedNumber passed_e(const Param& p, bool inches);      // E, in mm (inches: rounded, the rest carried)
    // Text passed on: what `list_` holds from `begin` on, with its effect on the firmware.
    void passed_text(std::size_t begin, cmd::Passthrough::Effect effect = cmd::Passthrough::Effect::None);
    void apply_modal(int code10, Params words);
    void run_command(const CommandWord& c, std::string_view body, bool alone, Params words, std::uint64_t line_no);
    void other_g(const CommandWord& c, std::string_view body, bool alone, Params words);
    void tool_move(int gcode, std::uint32_t column, Params words);
    // A tool move's words into `mv` (X Y Z, I J K, E, F, the rotaries); the tool vector I J K
    // into `ijk` when given (`ijk_column` its first word's column).
    bool read_tool_words(Params words, cmd::ToolMove& mv, Eigen::Vector3d& ijk, std::uint32_t& ijk_column);
    void arc(bool clockwise, std::uint32_t column, Params words);
    // The arc's words but E and F into `a` (E and F into `e`, `f`); true when a centre (I J K) was given.
    bool read_arc_words(Params words, cmd::Arc& a, std::optional<Param>& e, std::optional<Param>& f);
    void joint_move(int gcode, Params words);
    void joint_arc(int code10, std::string_view body, bool alone, Params words, std::uint32_t column);
    void set_position(Params words, std::string_view body);
    void home(Params words);
    // G68.2 (define a tilted plane), G53.1 (turn the tool to its +Z), G69 (cancel).
    void work_plane_command(const CommandWord& c, Params words, std::uint64_t line_no);
    void define_plane(const CommandWord& c, Params words, std::uint64_t line_no);
    template <class T>
    T& add() {
        return std::get<T>(list_->commands.emplace_back(std::in_place_type<T>));
    }

    const Machine& machine_;
    ModalState& state_;
    std::string input_name_;
    char extruder_letter_;
    std::string_view line_;             // the line read last
    cmd::CommandList* list_ = nullptr;  // where interpret() puts the line's commands
    LineSteps steps_;
    JointLetters letters_;
};

}  // namespace xlate5
