// SPDX-License-Identifier: GPL-3.0-or-later
// The lexer stage, after the line reader: one line of text -> a Block of words. Knows G-code
// syntax, nothing of its meaning. May call: number parsing.
#pragma once
#include <cstddef>
#include <cstdint>
#include <span>
#include <string_view>
#include <vector>

namespace xlate5 {

// (The fields in this order make a word 32 bytes, not 40: words are copied and stored often.)
struct Word {
    double value;            // NaN when the word has no number (a flag such as "G28 X")
    std::string_view text;   // the number as written (valid while the line is), to pass E on verbatim
    std::uint32_t column;    // 1-based column of the letter, for error messages
    char letter;             // upper case
    bool has_value;          // false for a flag or a quoted string argument (P"file.g")
};

// A word's letter (upper case A to Z) as one bit of a set of letters: 'A' is bit 0.
constexpr std::uint32_t letter_bit(char upper_case) { return 1u << (upper_case - 'A'); }

struct Block {
    // In line order; the leading N word and the *checksum are not here. Valid until the next
    // lex_line on this block.
    std::span<const Word> words() const { return {word_room.data(), word_count}; }
    std::string_view body;    // the line without N word, checksum, line end and surrounding blanks
    // The letters of words() (letter_bit): read_commands takes the common line (a G code first,
    // then distinct letters: as many letters as words) from these, not word by word.
    std::uint32_t letters = 0;
    bool has_comment = false;
    bool percent = false;     // a lone '%' (program delimiter of CNC files)
    bool text_argument = false;  // M117-style command whose free text follows (not words)
    // The file declared itself compact (kCompactDeclaration): a number directly followed by E and
    // an integer is read as two words. Unlike the flags above it is kept from line to line (a
    // file's dialect); lex_line only ever sets it.
    bool compact_words = false;
    bool empty() const { return word_count == 0; }

    // The lexer's storage, kept from line to line so that a line allocates nothing: the words
    // (the first word_count of word_room) and a copy of the line with a NUL after it, where the
    // scans of digits and blanks stop without testing the line's end at every character.
    std::vector<Word> word_room;
    std::size_t word_count = 0;
    std::vector<char> text;
};

// Largest magnitude accepted for any number: far beyond any machine, small enough that every
// later computation stays finite.
inline constexpr double kMaxNumber = 1e9;
// G, M and T numbers are codes: below this, so a code times ten (its decimal) fits an int with
// room to spare and no huge number can wrap around onto a real code.
inline constexpr double kMaxCode = 100000;

// A comment line of its own with this text (after ';' or inside '( )', any case, blanks around
// it allowed) declares the rest of the file compact: "X1.5E-05" is X1.5 and E-05, as compact
// G-code without spaces means it. Undeclared, such a number is refused, since it equally reads
// as the exponent 1.5e-05 (G-code has no exponents, but CAM programs that print floats do).
inline constexpr std::string_view kCompactDeclaration = "xlate5: compact-words";

// Lexes `line` (no trailing '\n'; a trailing '\r' is accepted) into `out`, reusing its storage.
// Throws LineError(column, message) for input it cannot accept. `nul_after`: a NUL follows the
// line (a std::string's text), so it is read in place, without Block::text's copy.
void lex_line(std::string_view line, Block& out, bool nul_after = false);

}  // namespace xlate5
