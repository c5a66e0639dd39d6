// The interpreter's first step (both directions): a block -> commands in RS274 order.
// What it may call: see line_commands.hpp.
#include "translators/line_commands.hpp"

#include <cmath>
#include <utility>

#include "translators/error.hpp"
#include "translators/number.hpp"

namespace xlate5 {

namespace {

// RS274's order of execution within a line for the mode-only codes (feed mode, plane, units,
// cutter compensation, tool length / TCP, coordinate system, path control, distance mode), so a
// line means the same whatever order its words are written in.
int modal_rank(int code10) {
    switch (code10) {
        case 930: case 940: return 0;
        case 170: case 180: case 190: return 1;
        case 200: case 210: return 2;
        case 400: case 410: case 420: return 3;
        case 434: case 435: case 490: return 4;
        case 610: case 611: case 640: return 6;
        case 900: case 910: case 901: case 911: return 7;
        case 800: return 8;
        default: return 5;  // G54..G59.3
    }
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

bool CommandWord::modal_only() const { return letter == 'G' && is_modal_only(code10); }

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

void append_passthrough(std::string& out, char letter, int code10, std::string_view body, bool alone, const Params& params) {
    if (alone) {
        out += body;
        out += '\n';
        return;
    }
    append_code(out, letter, code10);
    if (!(letter == 'G' && is_modal_only(code10))) {
        for (const auto& p : params) {
            out += ' ';
            out += p.letter;
            if (p.has_value) append_shortest(out, p.value);
        }
    }
    out += '\n';
}

void read_commands(const Block& block, char extruder_letter, LineCommands& out) {
    out.count = 0;
    out.params.clear();
    out.has_owner = false;
    auto find = [&](char letter) {
        for (const auto& p : out.params)
            if (p.letter == letter) return true;
        return false;
    };
    bool tool_word_is_param = false;
    for (const Word& w : block.words) {
        if (w.letter == 'G' || w.letter == 'M' || (w.letter == 'T' && !tool_word_is_param)) {
            if (out.count == LineCommands::kMax) throw LineError(w.column, "more than 16 commands on one line");
            const double scaled = w.value * 10.0;
            if (std::abs(scaled - std::round(scaled)) > 1e-6) throw LineError(w.column, std::string("command ") + w.letter + " has more than one decimal");
            out.commands[out.count++] = {w.letter, int(std::lround(scaled)), w.column};
            tool_word_is_param = w.letter == 'M' && m_takes_tool(out.commands[out.count - 1].code10);
            continue;
        }
        char letter = w.letter;
        if (letter == extruder_letter) letter = 'E';
        else if (letter == 'E' && extruder_letter != 'E')
            throw LineError(w.column, std::string("word E on a file whose extrusion letter is ") + extruder_letter);
        if (find(letter)) throw LineError(w.column, std::string("word ") + w.letter + " appears twice on this line");
        out.params.push_back({letter, w.value, w.column, w.has_value, w.text});
    }

    // G43.4/G43.5 H<n>: the tool length offset register of ISO controls. The tool length is the
    // machine file's, so the word is accepted and not used.
    for (std::size_t i = 0; i < out.count; ++i) {
        if (out.commands[i].letter != 'G' || (out.commands[i].code10 != 434 && out.commands[i].code10 != 435)) continue;
        for (auto it = out.params.begin(); it != out.params.end(); ++it)
            if (it->letter == 'H') {
                out.params.erase(it);
                break;
            }
    }

    // Mode-only codes run first, in RS274's order; then the line's command. (Insertion sort:
    // a line has a handful of commands, and std::stable_sort would allocate.)
    auto before = [](const CommandWord& a, const CommandWord& b) {
        const bool ma = a.modal_only(), mb = b.modal_only();
        if (ma != mb) return ma;
        return ma && modal_rank(a.code10) < modal_rank(b.code10);
    };
    for (std::size_t i = 1; i < out.count; ++i)
        for (std::size_t k = i; k > 0 && before(out.commands[k], out.commands[k - 1]); --k)
            std::swap(out.commands[k], out.commands[k - 1]);

    // At most one command on a line may own the words.
    std::size_t owners = 0;
    for (std::size_t i = 0; i < out.count; ++i) {
        const CommandWord& c = out.commands[i];
        if (c.modal_only()) continue;
        if (++owners == 2 && !out.params.empty())
            throw LineError(c.column, "two commands on this line take words: put them on separate lines");
        out.has_owner = true;
    }
}

}  // namespace xlate5
