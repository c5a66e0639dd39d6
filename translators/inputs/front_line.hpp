// SPDX-License-Identifier: GPL-3.0-or-later
// What the non-G-code front ends (apt_reader, waypoint_reader) hand to input_front: canonical
// tool-space G-code lines, each under the line number of the record it stands for, so that the
// interpreter, the planner, the look-back and the report work on them unchanged and every error
// names the record's own line. No stage of its own; calls nothing.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "translators/number.hpp"

namespace xlate5 {

struct FrontLine {
    std::uint64_t line_no = 0;
    std::string text;  // one G-code line, without '\n'
};
using FrontLines = std::vector<FrontLine>;

// " X1.25" etc.: a word with up to 9 decimals (finer than any machine; no exponent, which the
// lexer refuses). The values reaching it are range-checked by the readers (|v| <= 1e9).
inline void append_word(std::string& out, char letter, double v, int decimals = 9) {
    out += ' ';
    out += letter;
    append_fixed(out, v, decimals);
}

}  // namespace xlate5
