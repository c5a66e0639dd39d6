// The lexer stage, after the line reader: one line of text -> a Block of words. Knows G-code
// syntax, nothing of its meaning. May call: number parsing.
#pragma once
#include <cstdint>
#include <string_view>
#include <vector>

namespace xlate5 {

struct Word {
    char letter;             // upper case
    double value;            // NaN when the word has no number (a flag such as "G28 X")
    std::uint32_t column;    // 1-based column of the letter, for error messages
    bool has_value;          // false for a flag or a quoted string argument (P"file.g")
    std::string_view text;   // the number as written (valid while the line is), to pass E on verbatim
};

struct Block {
    std::vector<Word> words;  // in line order; the leading N word and the *checksum are not here
    std::string_view body;    // the line without N word, checksum, line end and surrounding blanks
    bool has_comment = false;
    bool percent = false;     // a lone '%' (program delimiter of CNC files)
    bool text_argument = false;  // M117-style command whose free text follows (not words)
    bool empty() const { return words.empty(); }
};

// Largest magnitude accepted for any number: far beyond any machine, small enough that every
// later computation stays finite.
inline constexpr double kMaxNumber = 1e9;

// Lexes `line` (no trailing '\n'; a trailing '\r' is accepted) into `out`, reusing its storage.
// Throws LineError(column, message) for input it cannot accept.
void lex_line(std::string_view line, Block& out);

}  // namespace xlate5
