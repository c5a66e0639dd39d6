// SPDX-License-Identifier: GPL-3.0-or-later
// The emitter stage: joint values -> firmware text. What it may call: see emitter.hpp.
#include "translators/pipeline/emitter.hpp"

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <limits>
#include <string>

#include "translators/error.hpp"
#include "translators/machine/firmware_config.hpp"
#include "translators/number.hpp"

namespace xlate5 {

int printed_decimals(const Machine& m, std::size_t j) { return m.joints[j].rotary ? m.dialect.rotary_decimals : m.dialect.linear_decimals; }

double printed_value(const Machine& m, std::size_t j, double v) {
    static constexpr double kPow10[] = {1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9};
    const int d = printed_decimals(m, j);
    long long units = 0;
    if (!to_units(v, d, units)) return v;
    return double(units) / kPow10[d];
}

void append_passed(std::string& out, const PassedNumber& n) {
    if (!n.text.empty()) out += n.text;
    else if (n.decimals >= 0) append_fixed(out, n.value, n.decimals);
    else append_shortest(out, n.value);
}

namespace {
void append_word(std::string& out, char letter, const PassedNumber& n) {
    out += ' ';
    out += letter;
    try {
        append_passed(out, n);
    } catch (const UnwritableNumber& e) {
        unwritable_word(letter, e);
    }
}

// Longest passed text JointEmitter::move copies into its line buffer; a longer one is appended.
constexpr std::size_t kPassedChars = 40;

// n (1 to kPassedChars) bytes from src to dst; up to 16 without a call, by two loads that may
// overlap (a passed E or F is a few characters), never reading past src + n.
inline void copy_short(char* dst, const char* src, std::size_t n) {
    if (n >= 8 && n <= 16) {
        std::uint64_t a, b;
        std::memcpy(&a, src, 8);
        std::memcpy(&b, src + n - 8, 8);
        std::memcpy(dst, &a, 8);
        std::memcpy(dst + n - 8, &b, 8);
    } else if (n >= 4 && n < 8) {
        std::uint32_t a, b;
        std::memcpy(&a, src, 4);
        std::memcpy(&b, src + n - 4, 4);
        std::memcpy(dst, &a, 4);
        std::memcpy(dst + n - 4, &b, 4);
    } else if (n < 4) {
        dst[0] = src[0];
        dst[n / 2] = src[n / 2];
        dst[n - 1] = src[n - 1];
    } else {
        std::memcpy(dst, src, n);
    }
}

// Whether the n bytes at a and b are the same; up to 16 without a call or a byte loop, by two
// compares that may overlap (a feed's text is a few characters), never reading past n.
inline bool same_short(const char* a, const char* b, std::size_t n) {
    if (n >= 8 && n <= 16) {
        std::uint64_t a0, a1, b0, b1;
        std::memcpy(&a0, a, 8);
        std::memcpy(&b0, b, 8);
        std::memcpy(&a1, a + n - 8, 8);
        std::memcpy(&b1, b + n - 8, 8);
        return ((a0 ^ b0) | (a1 ^ b1)) == 0;
    }
    if (n >= 4 && n < 8) {
        std::uint32_t a0, a1, b0, b1;
        std::memcpy(&a0, a, 4);
        std::memcpy(&b0, b, 4);
        std::memcpy(&a1, a + n - 4, 4);
        std::memcpy(&b1, b + n - 4, 4);
        return ((a0 ^ b0) | (a1 ^ b1)) == 0;
    }
    if (n == 0) return true;
    if (n < 4) return a[0] == b[0] && a[n / 2] == b[n / 2] && a[n - 1] == b[n - 1];
    return std::memcmp(a, b, n) == 0;
}

// Three decimals below 1000000 in magnitude (|units| < 1000000000): what write_units writes for
// them (a sign, the integer part from one table entry, or two past 1000, the fraction from a
// third), inline.
inline char* write_units3(char* p, long long units) {
    *p = '-';
    p += units < 0;
    const unsigned u = unsigned(units < 0 ? -units : units);
    const unsigned i = u / 1000;
    p = i < 1000 ? put_short(p, kIntegerText[i]) : put_short(put_short(p, kIntegerText[i / 1000]), kThreeDigits[i % 1000]);
    return put_short(p, kFraction3Text[u % 1000]);
}

// A joint value on to_units' path but not the move's usual two (three decimals below a million):
// write_units. Out of line, so the move's loop is laid out for the usual joints alone.
[[gnu::noinline]] char* write_joint_units(char* p, long long units, int decimals) { return write_units(p, units, decimals); }

// The word append_word would write, into a buffer at p (room: 2 + max(kPassedChars,
// kUnitsChars)): a passed text up to kPassedChars, or a computed value on to_units' path (what
// append_fixed writes). Null, with nothing written, for any other: append_word's to write.
[[gnu::always_inline]] inline char* put_passed_word(char* p, char letter, const PassedNumber& n) {
    long long units = 0;
    const bool text = !n.text.empty() && n.text.size() <= kPassedChars;
    if (!text && !(n.text.empty() && n.decimals >= 0 && to_units(n.value, n.decimals, units))) return nullptr;
    *p++ = ' ';
    *p++ = letter;
    if (!text) return write_units(p, units, n.decimals);
    copy_short(p, n.text.data(), n.text.size());
    return p + n.text.size();
}
}  // namespace

// E and F end a move line; a line that got no word at all (nothing changed) is taken back.
void finish_move(std::string& out, std::size_t start, std::size_t empty, const std::optional<PassedNumber>& e,
                 const std::optional<PassedNumber>& f) {
    if (e) append_word(out, 'E', *e);
    if (f) append_word(out, 'F', *f);
    if (out.size() == empty) out.resize(start);
    else out += '\n';
}

JointEmitter::JointEmitter(const Machine& machine) : machine_(&machine), joints_(machine.joints.size()) {
    if (joints_ > kMaxJoints) throw MachineError(machine.source_path + ": more joints than the emitter holds (" + std::to_string(kMaxJoints) + ")");
    const std::vector<double> home = machine.home_joints();
    std::copy(home.begin(), home.end(), believed_.begin());
    for (std::size_t j = 0; j < joints_; ++j) {
        word_[j] = {' ', machine.joints[j].output};
        absent_[j] = machine.joints[j].absent;
        decimals_[j] = machine.joints[j].rotary ? machine.dialect.rotary_decimals : machine.dialect.linear_decimals;
        // |v * 1000| < 999999.5: to_units gives |units| < 1000000 (v * 1000 is its scaled value, v
        // far inside kMaxWritten), write_units' three-decimal inline case.
        small_below_[j] = decimals_[j] == 3 ? 999999.5 : -1.0;
        // The same below 999999999.5: |units| < 1000000000, write_units3's range (a multi-turn rotary).
        wide_below_[j] = decimals_[j] == 3 ? 999999999.5 : -1.0;
    }
}

void JointEmitter::format(std::string& text, std::size_t joint, double value) const {
    try {
        append_fixed(text, value, decimals(joint));
    } catch (const UnwritableNumber& e) {
        unwritable_word(machine_->joints[joint].output, e);
    }
}

void JointEmitter::append_joint(std::string& out, std::size_t joint, double value) const {
    out += ' ';
    out += machine_->joints[joint].output;
    format(out, joint, value);
}

void JointEmitter::invalidate(const std::vector<double>& q) {
    known_.fill(false);
    std::copy(q.begin(), q.begin() + std::ptrdiff_t(std::min(q.size(), joints_)), believed_.begin());
}

// A move's line is built in a buffer of this many characters: the command, every joint word, E
// and F, the line end.
constexpr std::size_t kLineChars = 2 + kMaxJoints * (2 + kUnitsChars) + 2 * (2 + std::max(kPassedChars, kUnitsChars)) + 1;

namespace {
// E or F passed on, into the line buffer at p; a word off the fast path flushes the buffer
// (`line` to p) to `out` and is appended by the general code. Returns where the line goes on.
[[gnu::always_inline]] inline char* put_passed(std::string& out, char* line, char* p, char letter, const PassedNumber& n) {
    if (char* q = put_passed_word(p, letter, n)) return q;
    out.append(line, p);
    append_word(out, letter, n);
    return line;
}

// The line buffer (`line` to p, its line end written) to `out`. A line of up to kBlock
// characters (most) goes as a block of that fixed size, copied without a library call, and
// `out` is cut back to the line's end (erase to the end is inline).
[[gnu::always_inline]] inline void append_line(std::string& out, const char* line, const char* p) {
    constexpr std::size_t kBlock = 64;
    static_assert(kLineChars >= kBlock, "the block is read from the line buffer");
    if (const std::size_t n = std::size_t(p - line); n <= kBlock) {
        const std::size_t size = out.size();
        out.append(line, kBlock);
        out.erase(size + n);
    } else {
        out.append(line, p);
    }
}
}  // namespace

// A detour the observer asked for, before the piece: checked already, so written without the
// observer, at the piece's feed, uncompensated (the check re-routes only machines without
// compensation).
[[gnu::noinline]] void JointEmitter::write_detour(std::string& out, const std::vector<std::vector<double>>& detour,
                                                  const std::optional<PassedNumber>& f, bool inverse_time) {
    PieceObserver* const watching = observer_;
    observer_ = nullptr;
    for (const auto& w : detour) move(out, 0, w, w, JointBits(0), std::nullopt, f, inverse_time);
    observer_ = watching;
}

// F is modal in the firmware: written when its text changes (under G93 every move carries its
// own), and remembered when it fits kFText. Into the line buffer at p (`line` its start, flushed
// to `out` for a word off the fast path); returns where the line goes on.
[[gnu::always_inline]] inline char* JointEmitter::put_f(std::string& out, char* line, char* p, const PassedNumber& f) {
    // A computed F (the motion stage's, most moves): its digits go straight into the line
    // after the room for " F" and are compared there with the last; taken back (p stays)
    // when the same. What append_fixed would write, as the path below writes it: the usual
    // one decimal below a million by one test (|value * 10| < 9999999.5: to_units' units
    // below 10000000, write_units' one-decimal inline case), any other by to_units.
    static_assert(kUnitsChars <= kFText, "a computed F is always remembered");
    char* const digits = p + 2;
    char* end = nullptr;
    if (f.text.empty() && f.decimals >= 0) {
        const double scaled = f.value * 1e1;
        long long units = 0;
        if (f.decimals == 1 && std::abs(scaled) < 9999999.5) end = write_units1_small(digits, round_half_away(scaled));
        else if (to_units(f.value, f.decimals, units)) end = write_units(digits, units, f.decimals);
    }
    if (end) {
        const std::size_t n = std::size_t(end - digits);
        if (!inverse_time_ && n == last_f_size_ && same_short(digits, last_f_.data(), n)) return p;
        if (!inverse_time_) {
            // A fixed size (the line has room for kUnitsChars after `digits`): no memcpy
            // call; only the first n bytes are ever read back.
            std::memcpy(last_f_.data(), digits, kUnitsChars);
            last_f_size_ = n;
        }
        p[0] = ' ';
        p[1] = 'F';
        return end;
    }
    // Passed text, or a value off the fast path: the text as it will be written.
    const bool remembered = !f.text.empty() && f.text.size() <= kFText;
    if (!remembered) {  // too long to remember, or computed: written, nothing remembered
        last_f_size_ = 0;
    } else if (!inverse_time_ && f.text == std::string_view(last_f_.data(), last_f_size_)) {
        return p;
    } else if (!inverse_time_) {
        std::memcpy(last_f_.data(), f.text.data(), f.text.size());
        last_f_size_ = f.text.size();
    }
    return put_passed(out, line, p, 'F', f);
}

void JointEmitter::move(std::string& out, int gcode, std::span<const double> q, std::span<const double> sent,
                        JointBits commanded, std::optional<PassedNumber> e, std::optional<PassedNumber> f,
                        bool inverse_time) {
    if (observer_) {
        if (const auto* detour = observer_->piece(std::span<const double>(believed_.data(), q.size()), q, e))
            write_detour(out, *detour, f, inverse_time);
    }
    if (inverse_time != inverse_time_) {
        out += inverse_time ? "G93\n" : "G94\n";
        inverse_time_ = inverse_time;
        last_f_size_ = 0;
    }
    // The whole line goes into a buffer first and to the output in one piece. A word off the
    // fast path (a joint beyond to_units' range, a long or unusual E or F) flushes the buffer
    // and is appended by the general code, so `out` grows in the same order either way.
    char line[kLineChars];
    char* p = line;
    const std::size_t start = out.size();
    *p++ = 'G';
    *p++ = gcode == 0 ? '0' : '1';
    for (std::size_t j = 0; j < q.size(); ++j) {
        if (absent_[j]) continue;  // an axis the machine does not have
        long long units = 0;
        const int d = decimals(j);
        // The usual joint (three decimals, below 1000 in magnitude): one test, then what to_units
        // and write_units do for it; the same for a multi-turn rotary past 1000 (below a million)
        // by a second test. Any other: to_units' own tests.
        const double scaled = sent[j] * 1e3;
        const bool small = std::abs(scaled) < small_below_[j];
        bool wide = false, fast = true;
        if (small) units = round_half_away(scaled);
        else if ((wide = std::abs(scaled) < wide_below_[j])) units = round_half_away(scaled);
        else fast = to_units(sent[j], d, units);
        if (!fast) units = std::numeric_limits<long long>::min();  // never equal: always written
        const bool write = known_[j] ? units != last_[j] : ((commanded >> j & 1u) != 0 || q[j] != believed_[j]);
        believed_[j] = q[j];
        if (!write) continue;
        last_[j] = units;
        known_[j] = true;
        std::memcpy(p, word_[j].data(), 2);
        p += 2;
        if (small) {
            p = write_units3_small(p, units);
        } else if (wide) {
            p = write_units3(p, units);
        } else if (fast) {
            p = write_joint_units(p, units, d);
        } else {
            out.append(line, p);
            p = line;
            format(out, j, sent[j]);
        }
    }
    // E and F end the line, as finish_move ends it elsewhere.
    if (e) p = put_passed(out, line, p, 'E', *e);
    if (f) p = put_f(out, line, p, *f);
    // Nothing changed (no word after the command, none flushed to `out` either): no line.
    if (p == line + 2 && out.size() == start) return;
    *p++ = '\n';
    append_line(out, line, p);
    ++moves_written_;
}

void JointEmitter::set_position(std::string& out, std::span<const double> q, std::span<const double> sent,
                                JointBits which, std::optional<PassedNumber> e) {
    if (observer_ && e) observer_->e_set(e->value);
    // Klipper's G92 reads X Y Z E alone, and one with none of them sets all four to 0: an extra
    // axis is set through its manual stepper, which takes SET_POSITION only while unregistered
    // from its G-code letter. Those lines go after the G92 of the others (if any).
    const bool klipper = machine_->dialect.firmware == FirmwareDialect::Klipper;
    std::string steppers;
    const std::size_t start = out.size();
    out += "G92";
    const std::size_t empty = out.size();
    for (std::size_t j = 0; j < q.size(); ++j) {
        if ((which >> j & 1u) == 0 || absent_[j]) continue;
        const Joint& J = machine_->joints[j];
        if (klipper && J.output != 'X' && J.output != 'Y' && J.output != 'Z') {
            long long units = 0;
            if (!to_units(sent[j], decimals(j), units)) units = std::numeric_limits<long long>::min();
            last_[j] = units;
            known_[j] = true;
            believed_[j] = q[j];
            for (const char* then : {" GCODE_AXIS=\n", " SET_POSITION="}) {
                steppers += "MANUAL_STEPPER STEPPER=";
                steppers += J.manual_stepper;
                steppers += then;
            }
            format(steppers, j, sent[j]);
            steppers += '\n';
            steppers += klipper_register(J);
            continue;
        }
        long long units = 0;
        if (!to_units(sent[j], decimals(j), units)) units = std::numeric_limits<long long>::min();
        last_[j] = units;
        known_[j] = true;
        believed_[j] = q[j];
        out += ' ';
        out += machine_->joints[j].output;
        format(out, j, sent[j]);
    }
    if (e) append_word(out, 'E', *e);
    if (out.size() == empty) out.resize(start);
    else out += '\n';
    out += steppers;
}

}  // namespace xlate5

namespace xlate5 {

void fit_marlin_lines(std::string& out, std::size_t start, std::string_view input, bool text_argument,
                      const std::function<void(std::string_view)>& shortened) {
    std::size_t at = start;
    while (at < out.size()) {
        std::size_t nl = out.find('\n', at);
        if (nl == std::string::npos) nl = out.size();
        const std::string_view l(out.data() + at, nl - at);
        const bool display = l.rfind("M117", 0) == 0 || l.rfind("M118", 0) == 0;
        // What Marlin stores: up to a ';' comment (the text of a display or file command is
        // taken whole: xlate5 passes it on as written, ';' and all).
        std::size_t stored = l.size();
        const bool text = display || text_argument;
        if (!text)
            if (const auto semi = l.find(';'); semi != std::string_view::npos) stored = semi;
        if (stored > kMarlinLineChars && !(l.size() > 0 && l.front() == ';')) {
            if (!display) {
                // The column of the input where the 96th character of the written line is, when
                // the line was written as read; else the line's start.
                const auto in_at = input.find(l.substr(0, kMarlinLineChars + 1));
                const std::uint32_t column = in_at == std::string_view::npos ? 1 : std::uint32_t(in_at + kMarlinLineChars + 1);
                throw LineError(column, "this line would be written with " + std::to_string(stored) + " characters: Marlin reads at most " +
                                            std::to_string(kMarlinLineChars) + " and runs the rest as a line of its own; shorten it");
            }
            // A display text loses its tail; nothing is run from it.
            std::size_t keep = kMarlinLineChars;
            while (keep > 4 && l[keep - 1] == ' ') --keep;
            out.erase(at + keep, nl - (at + keep));
            nl = at + keep;
            if (shortened) shortened(l.substr(0, 4));
        }
        at = nl + 1;
    }
}

}  // namespace xlate5
