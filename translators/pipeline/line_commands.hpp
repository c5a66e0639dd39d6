// SPDX-License-Identifier: GPL-3.0-or-later
// The interpreter's first step, shared by both directions: a lexed block -> its commands (G, M,
// T codes) in RS274's order of execution and its parameter words, and back to text for lines
// passed on unchanged. Knows the shape of a line, nothing of a machine's state. May call: the
// lexer's types and number formatting.
#pragma once
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "translators/inputs/gcode_lexer.hpp"
#include "translators/pipeline/modes.hpp"

namespace xlate5 {

// A parameter word of a line (X, E, F, I ...), the extrusion letter already read as E: a word
// as the lexer gives it.
using Param = Word;
// A line's parameter words, or a command's: a view of the lexer's words where they can be taken
// as they are, else of a list rewritten from them (ParamList).
using Params = std::span<const Param>;
using ParamList = std::vector<Param>;

// G codes that only set a mode and take no words.
bool is_modal_only(int code10);

// A command word: letter and code times ten (G43.4 -> 434).
struct CommandWord {
    char letter;
    int code10;
    std::uint32_t column;
    // A G code that only sets a mode and takes no words. Inline, and G0 to G3 (below G17) at once:
    // asked of every command.
    bool modal_only() const { return letter == 'G' && code10 >= 170 && is_modal_only(code10); }
};

struct LineCommands {
    static constexpr std::size_t kMax = 16;
    CommandWord commands[kMax];
    std::size_t count = 0;     // in RS274's order of execution (execution_rank), stable
    Params params;             // the block's own words after its commands, or `rewritten`
    std::uint32_t letters = 0; // the letters of `params` (letter_bit)
    bool has_owner = false;    // a command that takes the words (not mode-only)
    bool alone() const { return count == 1; }
    // The params when they cannot be a view of the block's words: a command after a word, the
    // extrusion letter read as E, a G43.4 H word dropped.
    ParamList rewritten;
};

// Reads `block` into `out` (reusing its storage). `extruder_letter` is the input letter that
// carries extrusion. `out.params` may view the block's words: valid until its next lex_line.
// Throws LineError(column, cause).
void read_commands(const Block& block, char extruder_letter, LineCommands& out);

// A command's step in RS274's order of execution within a line (LinuxCNC's list): feed mode,
// S, T, M6, M3-M5, M7-M9, other M codes, G4, plane, units, cutter and length compensation,
// coordinate system, path control, distance mode (and M82/M83 with it), G28/G92, motion, and
// the stops M0 M1 M2 M30 M60 last. Letter 'S' is a spindle speed with no code to take it.
int execution_rank(const CommandWord& c);

// One step of a line: a command and the words it takes.
struct LineStep {
    CommandWord command;             // 'S': a spindle speed word on its own; the implicit motion is G0..G3
    Params words;                    // the line's params, or one of the plan's lists
    bool verbatim = false;           // the line's only command: passed on as written
};

// A line's steps in order of execution. A line that has a move and M/T codes (or S) is split:
// the move takes its words, the M code its own, each on its own line; a move never leaves
// with a code's words or a code with the move's.
struct LinePlan {
    static constexpr std::size_t kMax = LineCommands::kMax + 2;
    LineStep steps[kMax];
    std::size_t count = 0;
    ParamList move_words, speed;     // a split line's words, shared out
    ParamList code_words[LineCommands::kMax];
};

// Plans `line` given the modal motion (`motion`: 0..3, -1 none). `move_letters`: the letters of
// a move (X Y Z I J K E F and the machine's joints); `position_letters` those that place a
// joint. Throws LineError(column, cause) for words no command can take.
void plan_line(const LineCommands& line, int motion, std::string_view move_letters, std::string_view position_letters, LinePlan& out);

// "G1", "G43.4", "M104".
void append_code(std::string& out, char letter, int code10);

// A command passed on to the firmware: the line as written when it is the line's only command,
// else the command and (unless mode-only) the line's words. Letter 'S': the words alone.
void append_passthrough(std::string& out, char letter, int code10, std::string_view body, bool alone, Params params);

// An S, M or T command, which both directions pass on as written (M82/M83 also set E's mode in
// `modes`). False for a G command, which the caller interprets.
bool pass_non_g(const CommandWord& c, std::string_view body, bool alone, Params words, Modes& modes, std::string& out);

// A line with no words: its text (a comment), or an empty line for a blank one, or nothing.
void append_wordless(std::string& out, std::string_view line, const Block& block);

}  // namespace xlate5
