// SPDX-License-Identifier: GPL-3.0-or-later
// The interpreter stage, between the lexer and the planner: one line's words + the modal state
// (G43.4/G43.5/G49, G90/G91, G20/G21, G17-G19, G93/G94, M82/M83, F, G92's program frame, the
// tilted work plane of G68.2/G53.1/G69) ->
// typed commands: a ToolMove (G0/G1 under tool-centre-point control; each chord of a G2/G3), a
// JointMove (G49), a position set (G92), homing (G28), or the line passed on as written. Lines it
// does not need to understand pass through unchanged and in order. A failed line leaves neither
// output nor state changed.
// May call: the lexer, line_commands, arcs (G2/G3 -> chords), work_plane (the plane's frame), the
// keep-out stage, the planner.
#pragma once
#include <functional>
#include <array>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>

#include "translators/inputs/gcode_lexer.hpp"
#include "translators/kinematics/kinematics.hpp"
#include "translators/pipeline/collide.hpp"
#include "translators/pipeline/line_commands.hpp"
#include "translators/machine/machine.hpp"
#include "translators/pipeline/modes.hpp"
#include "translators/pipeline/planner.hpp"
#include "translators/pipeline/work_plane.hpp"

namespace xlate5 {

// The interpreter's own state.
struct ModalState {
    OrientationMode mode = OrientationMode::Angles;
    Modes modes;
    Eigen::Vector3d offset = Eigen::Vector3d::Zero();  // program frame origin in the part frame (G92)
    StampedPlane plane;  // G68.2 ... G69: X Y Z are read in the plane's frame (work_plane.hpp)
};

// The state a line can change above the emitter: rolled back as one when a line fails.
struct LineState {
    ModalState modal;
    PlannerState planner;
    CollideCursor collide;  // the collision stage's place in the printed part: rolled back with the line
};

class KeepOutStage;

// MAX_CMD_SIZE - 1: the characters Marlin reads of a line (PROTOCOL.md rule 4).
inline constexpr std::size_t kMarlinLineChars = 95;

// The letters that name an axis in a command's words on `machine`: X Y Z, the arc's I J K and
// the machine's joints. The service reads G28's words with it too (homes_all).
bool is_axis_letter(const Machine& machine, char letter);

class Interpreter {
public:
    Interpreter(const Kinematics& kinematics, LineState& state, Planner& planner, std::string input_name, char extruder_letter);

    // Interprets one line (without '\n'), appending its output to `out`. Throws InputError
    // naming the file, line (run.line_no) and column; the state is then as before the line and
    // the firmware's position is taken as unknown. `before`, when given, is the caller's own
    // copy of the state as it is now (the look-back takes one of every line): the line is undone
    // from it instead of from a second copy taken here.
    void feed_line(std::string_view line, LineRun& run, std::string& out, const LineState* before = nullptr);
    // Tool moves go through the keep-out stage (which sets R) before the planner, when set.
    void set_keep_out(KeepOutStage* stage) { keep_out_ = stage; }
    // The input is compact from its first line, as if it began with the compact declaration (gcode_lexer.hpp).
    void set_compact_words() { block_.compact_words = true; }
    // Where a notice goes (a display text shortened for the firmware's line length): stderr in
    // the command line; none: nothing is said.
    void set_notice(std::function<void(const std::string&)> notice) { notice_ = std::move(notice); }

private:
    // Marlin reads a line up to 95 characters and the rest as a new line (PROTOCOL.md rule 4):
    // every line this input line wrote is checked; display text is shortened, anything else refused.
    void check_line_lengths(std::string& out, std::size_t out_start, std::string_view line, std::uint64_t line_no);
    [[noreturn]] void fail(std::uint32_t column, const std::string& message) const;
    // The value, or an error if it is a flag. Inline: several words a line.
    double number(const Param& p) const {
        if (!p.has_value) no_number(p);
        return p.value;
    }
    [[noreturn]] void no_number(const Param& p) const;
    PassedNumber passed(const Param& p, bool inches) const;  // E or F, in mm
    PassedNumber passed_e(const Param& p, bool inches);      // E, in mm (inches: rounded, the rest carried)
    bool is_axis_letter(char c) const;
    // The rotary joint a word's letter names, -1 for none (a linear joint's letter, none, or a
    // letter tool_move reads as something else: X Y Z I J K E F).
    int rotary_of(char letter) const {
        const auto k = std::size_t(letter - 'A');
        return k < rotary_of_letter_.size() ? rotary_of_letter_[k] : -1;
    }
    // The joint a word's letter names, -1 for none: from a table made once, not a search of the
    // joints per word. (A word's letter is upper case A to Z, and no joint is named otherwise.)
    int joint_of(char letter) const {
        const auto k = std::size_t(letter - 'A');
        return k < joint_of_letter_.size() ? joint_of_letter_[k] : -1;
    }
    void apply_modal(int code10, Params words, std::string& out);
    void run_command(const CommandWord& c, std::string_view body, bool alone, Params words, LineRun& run, std::string& out);
    // A tool-space move; `absolute` and `inches` say how to read its words (an arc's chords are
    // absolute millimetres whatever the modes).
    void tool_move(int gcode, std::uint32_t column, Params words, bool absolute, bool inches, LineRun& run, std::string& out);
    void arc(bool clockwise, std::uint32_t column, Params words, LineRun& run, std::string& out);
    void joint_move(int gcode, Params words, std::string& out);
    void set_position(Params words, std::string_view body, std::string& out);
    void home(Params words, std::string& out);
    void set_move_commanded(std::uint32_t bits, std::size_t joints);
    void track_extrusion(const std::optional<PassedNumber>& e);
    // G68.2 (define a tilted plane), G53.1 (turn the tool to its +Z), G69 (cancel).
    void work_plane_command(const CommandWord& c, Params words, LineRun& run, std::string& out);
    // The current tip in the frame the input's X Y Z are read in: the program frame, or inside a
    // tilted plane the plane's; and back to the part frame.
    Eigen::Vector3d input_frame_tip() const;
    Eigen::Vector3d part_from_input(const Eigen::Vector3d& p) const;

    const Machine& machine_;
    LineState& state_;
    Planner& planner_;
    KeepOutStage* keep_out_ = nullptr;
    std::string input_name_;
    std::function<void(const std::string&)> notice_;
    std::uint64_t noticed_line_ = 0;
    bool long_lines_matter_ = false;  // the firmware is Marlin's  // the look-back replays lines: each is told once
    char extruder_letter_;
    LineState saved_;          // the state before the current line (when the caller keeps none)
    Block block_;
    LineCommands commands_;
    LinePlan plan_;
    std::string move_letters_, position_letters_;  // see plan_line
    std::array<int, 26> joint_of_letter_;           // see joint_of
    std::array<int, 26> rotary_of_letter_;          // see rotary_of
    // Scratch reused line after line (no allocation on the hot path).
    std::vector<double> angles_, joints_, arc_angles_;
    std::vector<bool> commanded_, which_;
    // A tool move's commanded joints (ToolMove::commanded), rewritten from one bit a joint, and
    // those bits: only a flag that changed is written (set_move_commanded).
    std::vector<bool> move_commanded_;
    std::uint32_t move_commanded_bits_ = 0;
    std::uint32_t linear_joints_ = 0, rotary_joints_ = 0;  // one bit a joint, from the machine
    ParamList chord_words_, rotary_words_;
    std::vector<Eigen::Vector3d> chord_ends_;
};

}  // namespace xlate5
