// SPDX-License-Identifier: GPL-3.0-or-later
// The interpreter's first step (both directions): a block -> commands in RS274 order.
// What it may call: see line_commands.hpp.
#include "translators/pipeline/line_commands.hpp"

#include <array>
#include <cmath>
#include <cstdint>
#include <utility>

#include "translators/error.hpp"
#include "translators/number.hpp"

namespace xlate5 {

namespace {

// M and T codes after which the line's position words are a move (RS274: the modal motion),
// not the code's own parameters: tool change, spindle, coolant, stops, fan, heaters, E mode.
bool leaves_axis_words(const CommandWord& c) {
    if (c.letter == 'T') return true;
    if (c.letter != 'M') return false;
    switch (c.code10) {
        case 0: case 10: case 20: case 30: case 40: case 50: case 60: case 70: case 80: case 90:
        case 300: case 600: case 610: case 700: case 710: case 720: case 730: case 820: case 830:
        case 1040: case 1060: case 1070: case 1090: case 1400: case 1410: case 1900: case 1910:
        case 2040: case 2200: case 2210: case 2800: case 4000: case 420:
            return true;
        default:
            return false;
    }
}

// Firmware codes that take axis letters as their own settings (Marlin's reading: M92 X80 sets
// steps per mm, M203 B limits B's feed): the line is sent as written and holds no move.
bool axis_letters_are_settings(const CommandWord& c) {
    if (c.letter != 'M') return false;
    switch (c.code10) {
        case 170: case 180: case 840: case 920: case 1250: case 1500: case 2010: case 2030: case 2050: case 2060:
        case 2070: case 2080: case 2110: case 2180: case 2600: case 2610: case 2900: case 3500: case 3510: case 4220:
        case 4250: case 5690: case 5740: case 5840: case 6000: case 6650: case 6660: case 7010: case 7020: case 8510:
        case 9000: case 9060: case 9070: case 9130: case 9140: case 9150:
            return true;
        default:
            return false;
    }
}

// M codes that take no words at all (spindle stop, coolant): CNC programs put them on the line of
// a command that does (`G53 G49 Z30 M09`, `G43 H1 Z5 M08`); every word there is the other's.
bool takes_no_words(const CommandWord& c) {
    return c.letter == 'M' && (c.code10 == 50 || c.code10 == 70 || c.code10 == 80 || c.code10 == 90);
}

bool is_motion_code(const CommandWord& c) {
    return c.letter == 'G' && (c.code10 == 0 || c.code10 == 10 || c.code10 == 20 || c.code10 == 30);
}

// M-codes whose T word names a tool (M104 T1 S200), rather than T being a tool change.
bool m_takes_tool(int code10) {
    switch (code10) {
        case 1040: case 1050: case 1060: case 1070: case 1090: case 2000: case 2180: case 2210:
        case 3010: case 3030: case 3060: case 6000: case 7010: case 7020: case 9060: case 9130: case 9140:
            return true;
        default:
            return false;
    }
}

// A command word's code times ten, rounded half away from zero (the lexer keeps codes below
// 1e5, so the sum is exact); a value off a tenth by more than 1e-6 is refused.
[[noreturn, gnu::noinline, gnu::cold]] void fail_decimals(const Word& w) {
    throw LineError(w.column, std::string("command ") + w.letter + " has more than one decimal");
}

// (Inline, its error out of line: asked of every command.)
inline int code10_of(const Word& w) {
    // A whole code (G1, M104): ten times it, which the rounding below gives too, at less cost.
    const long long whole = static_cast<long long>(w.value);
    if (double(whole) == w.value) return int(whole * 10);
    const double scaled = w.value * 10.0;
    const long long code10 = static_cast<long long>(scaled < 0 ? scaled - 0.5 : scaled + 0.5);
    if (std::abs(scaled - double(code10)) > 1e-6) fail_decimals(w);
    return int(code10);
}

// The bits set in each 11-bit value.
constexpr auto kBitCount11 = [] {
    std::array<std::uint8_t, 2048> counts{};
    for (std::size_t v = 1; v < counts.size(); ++v) counts[v] = std::uint8_t(counts[v >> 1] + (v & 1));
    return counts;
}();

// The bits set in a set of letters (26 bits), from a table in three steps (the library's
// popcount is a call in the baseline x86-64 this is built for; counting in the register takes
// more instructions).
unsigned letter_count(std::uint32_t letters) {
    return unsigned(kBitCount11[letters & 0x7FF]) + kBitCount11[(letters >> 11) & 0x7FF] + kBitCount11[letters >> 22];
}

bool blank(std::string_view s) {
    for (char c : s)
        if (c != ' ' && c != '\t' && c != '\r') return false;
    return true;
}

}  // namespace

bool is_modal_only(int code10) {
    switch (code10) {
        case 170: case 180: case 190:              // plane
        case 200: case 210:                        // units
        case 400: case 410: case 420:              // cutter compensation
        case 434: case 435: case 490:              // tool-centre-point control
        case 540: case 550: case 560: case 570: case 580: case 590: case 591: case 592: case 593:
        case 610: case 611: case 640:              // path control
        case 800:                                  // canned cycle cancel
        case 900: case 910: case 901: case 911:    // distance modes
        case 930: case 940:                        // feed modes
            return true;
        default:
            return false;
    }
}

int execution_rank(const CommandWord& c) {
    if (c.letter == 'S') return 5;
    if (c.letter == 'T') return 6;
    if (c.letter == 'M') {
        const int m = c.code10 / 10;
        if (c.code10 % 10 != 0) return 13;
        if (m >= 62 && m <= 68) return 7;
        if (m == 6 || m == 61) return 8;
        if (m >= 3 && m <= 5) return 9;
        if (m >= 70 && m <= 73) return 10;
        if (m >= 7 && m <= 9) return 11;
        if (m >= 48 && m <= 53) return 12;
        if (m == 82 || m == 83) return 21;  // the E mode, with the distance mode (latest written wins)
        if (m == 0 || m == 1 || m == 2 || m == 30 || m == 60) return 25;
        return 13;
    }
    switch (c.code10) {
        case 930: case 940: return 3;
        case 40: return 14;
        case 170: case 180: case 190: return 15;
        case 200: case 210: return 16;
        case 400: case 410: case 420: return 17;
        case 434: case 435: case 490: return 18;
        case 540: case 550: case 560: case 570: case 580: case 590: case 591: case 592: case 593: return 19;
        case 610: case 611: case 640: return 20;
        case 900: case 910: case 901: case 911: return 21;
        case 800: return 22;
        case 280: case 300: case 100: case 920: return 23;
        default: return 24;
    }
}

void append_code(std::string& out, char letter, int code10) {
    out += letter;
    append_fixed(out, code10 / 10.0, 1);
}

void append_wordless(std::string& out, std::string_view line, const Block& block) {
    if (!block.body.empty()) {
        out += block.body;
        out += '\n';
    } else if (blank(line)) {
        out += '\n';
    }
}

bool pass_non_g(const CommandWord& c, std::string_view body, bool alone, Params words, Modes& modes, std::string& out) {
    if (c.letter == 'G') return false;
    if (c.letter == 'M' && c.code10 == 820) modes.e_relative = false;
    if (c.letter == 'M' && c.code10 == 830) modes.e_relative = true;
    // A spindle speed (laser power) on its own is passed on as its words alone.
    append_passthrough(out, c.letter, c.letter == 'S' ? 0 : c.code10, body, alone, words);
    return true;
}

void append_passthrough(std::string& out, char letter, int code10, std::string_view body, bool alone, Params params) {
    if (alone) {
        out += body;
        out += '\n';
        return;
    }
    if (letter != 'S') append_code(out, letter, code10);  // 'S': the words alone (a spindle speed)
    if (!(letter == 'G' && is_modal_only(code10))) {
        for (const auto& p : params) {
            if (letter != 'S' || &p != &params.front()) out += ' ';
            out += p.letter;
            if (p.has_value) append_shortest(out, p.value);
        }
    }
    out += '\n';
}

namespace {

// read_commands for any block but the bulk of a program's (see there).
[[gnu::noinline]] void read_other_commands(const Block& block, char extruder_letter, LineCommands& out) {
    const std::span<const Word> words = block.words();
    // Letters seen so far, one bit each (the lexer gives upper case A to Z, and the extrusion
    // letter is read as E).
    std::uint32_t seen = 0;
    // The letters read as commands: T too, except after an M code whose T names a tool.
    constexpr std::uint32_t kCodes = letter_bit('G') | letter_bit('M'), kCodesAndTool = kCodes | letter_bit('T');
    std::uint32_t command_letters = kCodesAndTool;
    // The params are the block's words after its commands, taken as they are, as long as the
    // commands all come first and no word is changed; else they are copied to `rewritten`, the
    // words so far (all of them after the commands) when the first reason is met.
    bool view = true;
    auto stop_viewing = [&](std::size_t at) {
        if (!view) return;
        view = false;
        out.rewritten.assign(words.begin() + std::ptrdiff_t(out.count), words.begin() + std::ptrdiff_t(at));
    };
    for (std::size_t k = 0; k < words.size(); ++k) {
        const Word& w = words[k];
        std::uint32_t bit = letter_bit(w.letter);
        if (bit & command_letters) {
            if (out.count == LineCommands::kMax) throw LineError(w.column, "more than 16 commands on one line");
            const int code10 = code10_of(w);
            if (k != out.count) stop_viewing(k);  // a command after a word
            out.commands[out.count++] = {w.letter, code10, w.column};
            command_letters = w.letter == 'M' && m_takes_tool(code10) ? kCodes : kCodesAndTool;
            continue;
        }
        char letter = w.letter;
        if (extruder_letter != 'E') {
            if (letter == extruder_letter) {
                letter = 'E';
                bit = letter_bit('E');
                stop_viewing(k);
            } else if (letter == 'E') {
                throw LineError(w.column, std::string("word E on a file whose extrusion letter is ") + extruder_letter);
            }
        }
        if (seen & bit) throw LineError(w.column, std::string("word ") + w.letter + " appears twice on this line");
        seen |= bit;
        if (!view) {
            out.rewritten.push_back(w);
            out.rewritten.back().letter = letter;
        }
    }

    // G43.4/G43.5 H<n>: the tool length offset register of ISO controls. The tool length is the
    // machine file's, so the word is accepted and not used.
    for (std::size_t i = 0; i < out.count && (seen & letter_bit('H')); ++i) {
        if (out.commands[i].letter != 'G' || (out.commands[i].code10 != 434 && out.commands[i].code10 != 435)) continue;
        stop_viewing(words.size());
        for (auto it = out.rewritten.begin(); it != out.rewritten.end(); ++it)
            if (it->letter == 'H') {
                out.rewritten.erase(it);
                break;
            }
    }
    out.params = view ? words.subspan(out.count) : Params(out.rewritten);
    out.letters = seen;

    // RS274's order of execution. (Insertion sort, stable: a line has a handful of commands,
    // and std::stable_sort would allocate.)
    for (std::size_t i = 1; i < out.count; ++i)
        for (std::size_t k = i; k > 0 && execution_rank(out.commands[k]) < execution_rank(out.commands[k - 1]); --k)
            std::swap(out.commands[k], out.commands[k - 1]);
    for (std::size_t i = 0; i < out.count; ++i)
        if (!out.commands[i].modal_only()) out.has_owner = true;
}

}  // namespace

void read_commands(const Block& block, char extruder_letter, LineCommands& out) {
    out.count = 0;
    out.has_owner = false;
    const std::span<const Word> words = block.words();
    // The bulk of a program from the block's letter set: no letter twice (as many letters as
    // words), no M, T or H, the extrusion letter E, and a G code only as the first word. Then the
    // line's one command (or none) is that G, no word is rewritten, and the words after it are
    // the params: what read_other_commands gives, without its steps per word. The G code is read as there.
    constexpr std::uint32_t kOther = letter_bit('M') | letter_bit('T') | letter_bit('H');
    if (extruder_letter == 'E' && !(block.letters & kOther) && letter_count(block.letters) == words.size() &&
        (!(block.letters & letter_bit('G')) || words.front().letter == 'G')) {
        std::size_t first = 0;
        if (block.letters & letter_bit('G')) {
            const Word& w = words.front();
            out.commands[0] = {w.letter, code10_of(w), w.column};
            out.count = 1;
            out.has_owner = !out.commands[0].modal_only();
            first = 1;
        }
        out.params = words.subspan(first);
        out.letters = block.letters & ~letter_bit('G');
        return;
    }
    read_other_commands(block, extruder_letter, out);
}

namespace {

bool has_letter(std::string_view letters, char c) { return letters.find(c) != std::string_view::npos; }

void add_step(LinePlan& out, const CommandWord& c, Params words, bool verbatim) {
    // In order of execution; stable among equals (the commands arrive sorted).
    std::size_t k = out.count++;
    for (; k > 0 && execution_rank(out.steps[k - 1].command) > execution_rank(c); --k) out.steps[k] = out.steps[k - 1];
    out.steps[k] = {c, words, verbatim};
}

// The motion in effect takes the words of a line that has no command to take them.
void add_modal_motion(LinePlan& out, int motion, Params words) {
    if (motion < 0) throw LineError(words.front().column, "axis words without a motion command (G0 or G1)");
    add_step(out, {'G', motion * 10, words.front().column}, words, false);
}

// A word a move takes: its letters, and R and P on an arc.
bool is_move_word(char c, std::string_view move_letters, bool arc) {
    return has_letter(move_letters, c) || (arc && (c == 'R' || c == 'P'));
}

// One command takes all the words (or none does: the modal motion). A code that takes no words
// leaves them to the other, on a line of its own.
void plan_one_owner(const LineCommands& line, int motion, std::string_view position_letters, LinePlan& out) {
    const Params words = line.params;
    std::size_t owners = 0, wordless = 0;
    for (std::size_t i = 0; i < line.count; ++i)
        if (!line.commands[i].modal_only() && takes_no_words(line.commands[i])) ++wordless;
    const bool others_take = wordless > 0 && line.count > wordless;  // another command is there to take them
    const CommandWord* first_owner = nullptr;
    for (std::size_t i = 0; i < line.count; ++i) {
        const CommandWord& c = line.commands[i];
        if (c.modal_only() || (others_take && takes_no_words(c))) continue;
        if (!first_owner) first_owner = &c;
        if (++owners == 2 && !words.empty()) {
            std::string a, b;
            append_code(a, first_owner->letter, first_owner->code10);
            append_code(b, c.letter, c.code10);
            throw LineError(words.front().column, "word " + std::string(1, words.front().letter) + " could belong to " + a + " or to " + b +
                                                      " (both take words): put each on a line of its own with its words");
        }
        if (c.letter == 'M' && !leaves_axis_words(c) && !axis_letters_are_settings(c))
            for (const auto& p : words)
                if (has_letter(position_letters, p.letter)) {
                    std::string code;
                    append_code(code, c.letter, c.code10);
                    throw LineError(p.column, "word " + std::string(1, p.letter) + " on a line with " + code +
                                                  ", a code not known to take axis words: a move goes on a line of its own");
                }
    }
    for (std::size_t i = 0; i < line.count; ++i)
        add_step(out, line.commands[i], line.commands[i].modal_only() || (others_take && takes_no_words(line.commands[i])) ? Params{} : words,
                 line.alone());
    if (!line.has_owner && !words.empty()) add_modal_motion(out, motion, words);
}

// The move (the line's motion command `motion_cmd`, or -1: the modal `motion`) takes its words;
// S goes to M3/M4 (else to the line's one M code, else on its own line); the other words go to
// the line's one M code (`m_codes` of them on the line).
void plan_split(const LineCommands& line, int motion, int motion_cmd, int m_codes, std::string_view move_letters, bool arc,
                LinePlan& out) {
    int speed_taker = -1, word_taker = -1;
    for (std::size_t i = 0; i < line.count; ++i) {
        const CommandWord& c = line.commands[i];
        if (c.letter != 'M') continue;
        if (speed_taker < 0 && (c.code10 == 30 || c.code10 == 40)) speed_taker = int(i);
        if (m_codes == 1) word_taker = int(i);
        out.code_words[i].clear();
    }
    if (speed_taker < 0) speed_taker = word_taker;
    for (const auto& p : line.params) {
        if (is_move_word(p.letter, move_letters, arc)) {
            out.move_words.push_back(p);
        } else if (p.letter == 'S' && speed_taker >= 0) {
            out.code_words[speed_taker].push_back(p);
        } else if (p.letter == 'S' && m_codes == 0) {
            out.speed.push_back(p);
        } else if (word_taker >= 0) {
            out.code_words[word_taker].push_back(p);
        } else if (m_codes == 0) {
            out.move_words.push_back(p);  // the move names the word it cannot take
        } else {
            throw LineError(p.column, "word " + std::string(1, p.letter) + " on a line with several M codes: put the code it belongs to on a line of its own");
        }
    }
    for (std::size_t i = 0; i < line.count; ++i) {
        const CommandWord& c = line.commands[i];
        if (c.modal_only()) add_step(out, c, {}, false);
        else if (c.letter == 'G') add_step(out, c, out.move_words, false);
        else add_step(out, c, c.letter == 'M' ? Params(out.code_words[i]) : Params{}, false);
    }
    if (!out.speed.empty()) add_step(out, {'S', 0, out.speed.front().column}, out.speed, false);
    if (motion_cmd < 0 && !out.move_words.empty()) add_modal_motion(out, motion, out.move_words);
}

// Any line but the bulk of a program (plan_line).
[[gnu::noinline]] void plan_other_line(const LineCommands& line, int motion, std::string_view move_letters, std::string_view position_letters,
                     LinePlan& out) {
    const Params words = line.params;
    const bool any_speed = (line.letters & letter_bit('S')) != 0;
    out.move_words.clear();
    out.speed.clear();

    // A lone S (spindle speed, laser power) is passed on as written.
    bool all_speed = line.count == 0 && !words.empty();
    for (std::size_t k = 0; all_speed && k < words.size(); ++k) all_speed = words[k].letter == 'S';
    if (all_speed) {
        add_step(out, {'S', 0, words.front().column}, words, true);
        return;
    }

    int motion_cmd = -1, codes = 0, m_codes = 0;
    bool other_owner = false, all_leave = true;
    for (std::size_t i = 0; i < line.count; ++i) {
        const CommandWord& c = line.commands[i];
        if (c.modal_only()) continue;
        if (c.letter == 'G') {
            if (is_motion_code(c) && motion_cmd < 0) motion_cmd = int(i);
            else other_owner = true;
            continue;
        }
        ++codes;
        if (c.letter == 'M') ++m_codes;
        all_leave = all_leave && leaves_axis_words(c);
    }
    const int arc_motion = motion_cmd >= 0 ? line.commands[motion_cmd].code10 / 10 : motion;
    const bool arc = arc_motion == 2 || arc_motion == 3;
    // A motion command moves whatever its words; the letters are looked up only without one.
    bool moves = motion_cmd >= 0;
    for (std::size_t k = 0; !moves && k < words.size(); ++k) moves = is_move_word(words[k].letter, move_letters, arc);
    const bool split = all_leave && !other_owner && ((codes >= 1 && moves) || codes >= 2 || (codes == 0 && any_speed && moves));
    if (split) plan_split(line, motion, motion_cmd, m_codes, move_letters, arc, out);
    else plan_one_owner(line, motion, position_letters, out);
}

}  // namespace

void plan_line(const LineCommands& line, int motion, std::string_view move_letters, std::string_view position_letters, LinePlan& out) {
    out.count = 0;
    const Params words = line.params;
    // The bulk of a program, planned here at once: a line of one motion command, or of none (the
    // modal motion), with no S (which a move leaves to a line of its own).
    if (!(line.letters & letter_bit('S'))) {
        if (line.count == 1 && is_motion_code(line.commands[0])) {
            LineStep& step = out.steps[0];  // (field by field: no copy through the stack)
            step.command = line.commands[0];
            step.words = words;
            step.verbatim = true;
            out.count = 1;
            return;
        }
        if (line.count == 0 && !words.empty()) {
            add_modal_motion(out, motion, words);
            return;
        }
    }
    plan_other_line(line, motion, move_letters, position_letters, out);
}

}  // namespace xlate5
