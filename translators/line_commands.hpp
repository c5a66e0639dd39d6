// The interpreter's first step, shared by both directions: a lexed block -> its commands (G, M,
// T codes) in RS274's order of execution and its parameter words, and back to text for lines
// passed on unchanged. Knows the shape of a line, nothing of a machine's state. May call: the
// lexer's types and number formatting.
#pragma once
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "translators/gcode_lexer.hpp"

namespace xlate5 {

// A parameter word of a line (X, E, F, I ...), the extrusion letter already read as E.
struct Param {
    char letter;
    double value;
    std::uint32_t column;
    bool has_value;
    std::string_view text;  // the number as written (valid while the line is)
};
using Params = std::vector<Param>;

// A command word: letter and code times ten (G43.4 -> 434).
struct CommandWord {
    char letter;
    int code10;
    std::uint32_t column;
    bool modal_only() const;  // a G code that only sets a mode and takes no words
};

struct LineCommands {
    static constexpr std::size_t kMax = 16;
    CommandWord commands[kMax];
    std::size_t count = 0;     // mode-only codes first, in RS274's order, then the rest
    Params params;
    bool has_owner = false;    // a command that takes the words (not mode-only)
    bool alone() const { return count == 1; }
};

// Reads `block` into `out` (reusing its storage). `extruder_letter` is the input letter that
// carries extrusion. Throws LineError(column, cause).
void read_commands(const Block& block, char extruder_letter, LineCommands& out);

// G codes that only set a mode and take no words.
bool is_modal_only(int code10);

// "G1", "G43.4", "M104".
void append_code(std::string& out, char letter, int code10);

// A command passed on to the firmware: the line as written when it is the line's only command,
// else the command and (unless mode-only) the line's words.
void append_passthrough(std::string& out, char letter, int code10, std::string_view body, bool alone, const Params& params);

// A line with no words: its text (a comment), or an empty line for a blank one, or nothing.
void append_wordless(std::string& out, std::string_view line, const Block& block);

}  // namespace xlate5
